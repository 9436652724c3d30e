"""nmci.stonesoup, in Stone Soup's test style (pytest, parametrised). Skipped when Stone Soup is
absent; the test command installs it."""

import datetime
import warnings

import numpy as np
import pytest

stonesoup = pytest.importorskip("stonesoup")

from scipy import integrate  # noqa: E402
from stonesoup.models.measurement.linear import LinearGaussian  # noqa: E402
from stonesoup.models.transition.linear import (  # noqa: E402
    CombinedLinearGaussianTransitionModel,
    ConstantVelocity,
    RandomWalk,
)
from stonesoup.mixturereducer.gaussianmixture import CovarianceIntersection  # noqa: E402
from stonesoup.serialise import YAML  # noqa: E402
from stonesoup.types.detection import Detection, GaussianDetection, MissedDetection  # noqa: E402
from stonesoup.types.hypothesis import SingleHypothesis  # noqa: E402
from stonesoup.types.multihypothesis import MultipleHypothesis  # noqa: E402
from stonesoup.types.prediction import (  # noqa: E402
    GaussianStatePrediction,
    TaggedWeightedGaussianStatePrediction,
)
from stonesoup.types.state import GaussianState  # noqa: E402
from stonesoup.types.track import Track  # noqa: E402
from stonesoup.updater.chernoff import ChernoffUpdater  # noqa: E402
from stonesoup.updater.kalman import KalmanUpdater  # noqa: E402
from stonesoup.updater.pointprocess import PHDUpdater  # noqa: E402
from stonesoup.updater.wrapper import DetectionAndTrackSwitchingUpdater  # noqa: E402

import nmci  # noqa: E402
from nmci.stonesoup import (  # noqa: E402
    NmciCovarianceIntersection,
    NmciUpdater,
    blocks_from_transition_model,
    chernoff_log_normaliser,
    fuse_tracks,
    innovation_covariance,
)

T0 = datetime.datetime(2026, 1, 1)


def spd(rng, n, blocks=None):
    g = rng.standard_normal((n, n))
    P = g @ g.T / n + 0.3 * np.eye(n)
    if blocks is not None:
        mask = np.zeros((n, n), dtype=bool)
        for b in blocks:
            mask[np.ix_(b, b)] = True
        P = np.where(mask, P, 0.0)
    return P


def hypothesis(a, A, b, B, timestamp=T0):
    n = len(a)
    model = LinearGaussian(ndim_state=n, mapping=tuple(range(n)), noise_covar=A)
    detection = GaussianDetection(np.reshape(a, (n, 1)), A, timestamp=timestamp, measurement_model=model)
    prediction = GaussianStatePrediction(np.reshape(b, (n, 1)), B, timestamp=timestamp)
    return SingleHypothesis(prediction, detection)


def test_the_plugin_entry_point_gives_the_package():
    from stonesoup.plugins.nmci import NmciUpdater as Plugged

    assert Plugged is NmciUpdater


@pytest.mark.parametrize("omega", [0.2, 0.5, 0.8])  # ChernoffUpdater divides by 1 - ω
@pytest.mark.parametrize("n, seed", [(n, seed) for n in (2, 4, 6) for seed in range(5)])
def test_a_fixed_omega_is_chernoff_updaters_update(omega, n, seed):
    rng = np.random.default_rng(100 * n + seed)
    a, b = rng.standard_normal(n), rng.standard_normal(n)
    A, B = spd(rng, n), spd(rng, n)
    ours = NmciUpdater(measurement_model=None, omega=omega).update(hypothesis(a, A, b, B))
    theirs = ChernoffUpdater(measurement_model=None, omega=omega).update(hypothesis(a, A, b, B))
    # Within 2e-14 of the largest entry (docs/python.md): inverses here, pseudo-inverses there.
    for mine, stone in ((ours.covar, theirs.covar), (ours.state_vector, theirs.state_vector)):
        assert np.abs(np.asarray(mine - stone, dtype=float)).max() <= 2e-14 * np.abs(stone).max()
    assert ours.fusion.omega == (omega,)


@pytest.mark.parametrize("seed", range(5))
def test_the_optimal_omega_is_never_worse_than_any_omega_on_a_grid(seed):
    rng = np.random.default_rng(seed)
    A, B = spd(rng, 3), spd(rng, 3)
    optimal = np.trace(NmciUpdater(measurement_model=None).update(hypothesis(np.zeros(3), A, np.zeros(3), B)).covar)
    for omega in np.linspace(0, 1, 101):
        fixed = NmciUpdater(measurement_model=None, omega=omega).update(hypothesis(np.zeros(3), A, np.zeros(3), B))
        assert optimal <= np.trace(fixed.covar) * (1 + 1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_nmci_is_never_looser_than_ci(seed):
    rng = np.random.default_rng(seed)
    blocks = [[0, 1], [2, 3]]
    A, B = spd(rng, 4, blocks), spd(rng, 4, blocks)
    h = hypothesis(rng.standard_normal(4), A, rng.standard_normal(4), B)
    ci = NmciUpdater(measurement_model=None, rule="ci").update(h)
    nm = NmciUpdater(measurement_model=None, rule="nmci", blocks=blocks).update(h)
    assert np.trace(nm.covar) <= np.trace(ci.covar) * (1 + 1e-12)
    assert nm.fusion.blocks == ((0, 1), (2, 3)) and len(nm.fusion.omega) == 2
    assert nm.fusion.guarantee == ci.fusion.guarantee == "conservative"


@pytest.mark.parametrize("rule", ["certified", "ici", "ei", "naive", "sdp", "sdp_cuts"])
def test_every_rule_of_the_registry_updates(rule):
    # The SDPs' update takes the bound proven for their own gain, not their relaxation's `p`.
    rng = np.random.default_rng(7)
    A, B = spd(rng, 2), spd(rng, 2)
    options = {"samples": 50} if rule == "sdp" else None
    up = NmciUpdater(measurement_model=None, rule=rule, options=options).update(
        hypothesis(np.ones(2), A, np.zeros(2), B))
    expected = nmci.fuse({"method": rule, "pa": A, "pb": B, "xa": np.ones(2), "xb": np.zeros(2), **(options or {})})
    sdp = rule in ("sdp", "sdp_cuts")
    covar = np.asarray(expected["gain_certified_p" if sdp else "p"])
    assert np.array_equal(up.covar, covar) and up.fusion.rule == rule
    assert np.array_equal(np.ravel(up.state_vector), expected["x"])
    assert (up.fusion.guarantee == "conservative") == (sdp or rule == "certified")
    if sdp:
        assert np.trace(covar) >= expected["trace"] and not np.array_equal(covar, expected["p"])


@pytest.mark.parametrize("omega", [0.3, 0.5, 0.8])
def test_the_normaliser_is_the_integral_in_one_dimension(omega):
    a, A, b, B = 0.7, 2.0, -0.4, 0.5
    density = lambda x, m, v: np.exp(-0.5 * (x - m) ** 2 / v) / np.sqrt(2 * np.pi * v)  # noqa: E731
    value, _ = integrate.quad(lambda x: density(x, a, A) ** omega * density(x, b, B) ** (1 - omega), -50, 50,
                              epsabs=0, epsrel=1e-13)
    assert chernoff_log_normaliser([a], [[A]], [b], [[B]], omega) == pytest.approx(np.log(value), abs=1e-10)


@pytest.mark.parametrize("omega", [0.3, 0.7])
def test_the_normaliser_is_the_integral_in_two_dimensions_and_stone_soups_matrix_is_not(omega):
    a, b = np.array([0.5, -0.2]), np.array([-0.3, 0.4])
    A = np.array([[1.0, 0.3], [0.3, 0.6]])
    B = np.array([[0.4, -0.1], [-0.1, 0.9]])

    def density(x, m, S):
        d = x - m
        return np.exp(-0.5 * d @ np.linalg.solve(S, d)) / np.sqrt(np.linalg.det(2 * np.pi * S))

    value, _ = integrate.dblquad(
        lambda y, x: density(np.array([x, y]), a, A) ** omega * density(np.array([x, y]), b, B) ** (1 - omega),
        -12, 12, -12, 12, epsabs=1e-13, epsrel=1e-11)
    ours = chernoff_log_normaliser(a, A, b, B, omega)
    assert ours == pytest.approx(np.log(value), abs=1e-8)
    # Stone Soup's innovation covariance A/(1-ω) + B/ω is V(1 - ω): its Gaussian factor, with the
    # same κ, is not the integral at ω ≠ 0.5.
    V_ss = A / (1 - omega) + B / omega
    V = innovation_covariance(A, B, omega)
    assert np.allclose(V, A / omega + B / (1 - omega))
    gauss = lambda S: -0.5 * (np.linalg.slogdet(2 * np.pi * S)[1] + (a - b) @ np.linalg.solve(S, a - b))  # noqa: E731
    theirs = ours - gauss(V) + gauss(V_ss)
    assert abs(theirs - np.log(value)) > 1e-3


@pytest.mark.parametrize("seed", range(20))
def test_the_innovation_covariance_bounds_every_cross_covariance(seed):
    rng = np.random.default_rng(seed)
    n = 3
    joint = spd(rng, 2 * n)
    A, B, C = joint[:n, :n], joint[n:, n:], joint[:n, n:]
    difference = A + B - C - C.T
    for omega in [None, 0.05, 0.5, rng.uniform(0.01, 0.99), 0.0, 1.0]:
        V = innovation_covariance(A, B, omega)
        assert np.linalg.eigvalsh(V - difference).min() >= -1e-12 * np.trace(V)


def test_predict_measurement_gives_v_at_the_weights():
    rng = np.random.default_rng(3)
    A, B = spd(rng, 2), spd(rng, 2)
    h = hypothesis(np.zeros(2), A, np.zeros(2), B)
    model = h.measurement.measurement_model
    half = NmciUpdater(measurement_model=None, omega=0.5).predict_measurement(h.prediction, model)
    chernoff = ChernoffUpdater(measurement_model=None, omega=0.5).predict_measurement(h.prediction, model)
    assert np.allclose(half.covar, chernoff.covar, rtol=1e-15)
    at = NmciUpdater(measurement_model=None, omega=0.3).predict_measurement(h.prediction, model)
    assert np.allclose(at.covar, A / 0.3 + B / 0.7, rtol=1e-15)
    optimal = NmciUpdater(measurement_model=None).predict_measurement(h.prediction, model)
    w = nmci.ci(A, B).omega[0]
    assert 0 < w < 1 and np.allclose(optimal.covar, A / w + B / (1 - w), rtol=1e-14)
    bare = NmciUpdater(measurement_model=None).predict_measurement(h.prediction, model, measurement_noise=False)
    assert np.array_equal(bare.covar, B)


def test_a_yaml_round_trip_gives_the_same_updater():
    updater = NmciUpdater(measurement_model=None, rule="nmci", blocks=[[0, 1], [2, 3]], coupling_tol=1e-8,
                          criterion="trace", pab_unknown=np.eye(4, dtype=bool))
    reducer = NmciCovarianceIntersection(rule="nmci", blocks=[[0], [1]])
    certified = NmciUpdater(measurement_model=None, rule="certified", options={"level": 2})
    for component in (updater, reducer, certified):
        text = YAML().dumps(component)
        assert "!nmci.stonesoup" in text
        back = YAML().load(text)
        assert type(back) is type(component)
        for name in type(component).properties:
            assert np.array_equal(np.asarray(getattr(back, name), dtype=object),
                                  np.asarray(getattr(component, name), dtype=object)), name


def test_inside_phd_updater():
    rng = np.random.default_rng(5)
    blocks = [[0, 1], [2, 3]]
    predictions = [
        TaggedWeightedGaussianStatePrediction(rng.standard_normal((4, 1)), spd(rng, 4, blocks), weight=0.5,
                                              tag=str(i), timestamp=T0)
        for i in range(2)]
    detections = []
    for _ in range(3):
        A = spd(rng, 4, blocks)
        detections.append(GaussianDetection(
            rng.standard_normal((4, 1)), A, timestamp=T0,
            measurement_model=LinearGaussian(ndim_state=4, mapping=(0, 1, 2, 3), noise_covar=A)))
    hypotheses = [MultipleHypothesis([SingleHypothesis(p, d) for p in predictions]) for d in detections]
    hypotheses.append(MultipleHypothesis([SingleHypothesis(p, MissedDetection(timestamp=T0)) for p in predictions]))
    phd = PHDUpdater(NmciUpdater(measurement_model=None, rule="nmci", blocks=blocks),
                     clutter_spatial_density=1e-3, prob_detection=0.9, prob_survival=0.99)
    mixture = phd.update(hypotheses)
    weights = [c.weight for c in mixture]
    assert len(mixture) == 3 * 2 + 2 and all(np.isfinite(float(w)) and float(w) >= 0 for w in weights)
    # PHDUpdater rebuilds its components from mean and covariance; the fusion details survive
    # on the hypotheses it keeps, as the declared Property of their measurement predictions.
    for multi in mixture.hypothesis[:-1]:
        for h in multi:
            info = h.measurement_prediction.fusion
            assert "fusion" in type(h.measurement_prediction).properties
            assert info.rule == "nmci" and info.blocks == ((0, 1), (2, 3)) and len(info.omega) == 2


def test_the_fusion_details_are_a_declared_property_of_stone_soups_own_kinds():
    rng = np.random.default_rng(12)
    B = spd(rng, 4, [[0, 1], [2, 3]])
    A = spd(rng, 4, [[0, 1], [2, 3]])
    a, b = rng.standard_normal(4), rng.standard_normal(4)
    from stonesoup.types.update import GaussianStateUpdate, TaggedWeightedGaussianStateUpdate
    from nmci.stonesoup import FusionInfo, FusionRecord

    update = NmciUpdater(None, rule="nmci", blocks=[[0, 1], [2, 3]]).update(hypothesis(a, A, b, B))
    assert isinstance(update, GaussianStateUpdate) and isinstance(update, FusionRecord)
    assert type(update).__name__ == "NmciGaussianStateUpdate"
    # Declared, last (so Stone Soup's positional order is kept), and in the repr.
    assert list(type(update).properties)[-1] == "fusion"
    assert isinstance(update.fusion, FusionInfo) and "fusion=FusionInfo(" in repr(update)
    assert update.hypothesis.measurement_prediction.fusion == update.fusion
    # A copy by Stone Soup's from_state keeps it; a pickle round trip too.
    import pickle
    again = pickle.loads(pickle.dumps(update))
    assert type(again) is type(update) and again.fusion == update.fusion
    assert GaussianStateUpdate.from_state(update, target_type=type(update)).fusion == update.fusion
    # A PHD component's prediction gives Stone Soup's tagged kind, extended.
    prediction = TaggedWeightedGaussianStatePrediction(
        np.reshape(b, (4, 1)), B, weight=0.5, tag="t1", timestamp=T0)
    h = hypothesis(a, A, b, B)
    tagged = NmciUpdater(None).update(SingleHypothesis(prediction, h.measurement))
    assert isinstance(tagged, TaggedWeightedGaussianStateUpdate) and tagged.tag == "t1"
    assert tagged.fusion.rule == "ci"
    # The reducer's merge: the first component's kind, extended.
    merged = NmciCovarianceIntersection().merge_components(GaussianState(a, A), GaussianState(b, B))
    assert type(merged).__name__ == "NmciGaussianState" and merged.fusion.rule == "ci"


def test_inside_a_detection_and_track_switching_tracker():
    """Detections go to a Kalman updater, tracks from another node to NmciUpdater."""
    rng = np.random.default_rng(11)
    transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1), ConstantVelocity(0.1)])
    blocks = blocks_from_transition_model(transition)
    position = LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.eye(2) * 0.5)
    updater = DetectionAndTrackSwitchingUpdater(
        None, KalmanUpdater(position), NmciUpdater(measurement_model=None, rule="nmci", blocks=blocks))
    from stonesoup.predictor.kalman import KalmanPredictor

    predictor = KalmanPredictor(transition)
    state = GaussianState(np.zeros((4, 1)), np.eye(4), timestamp=T0)
    for k in range(1, 11):
        t = T0 + datetime.timedelta(seconds=k)
        prediction = predictor.predict(state, timestamp=t)
        if k % 2:
            z = Detection(rng.standard_normal((2, 1)), timestamp=t, measurement_model=position)
        else:
            A = np.diag([0.4, 0.1, 0.4, 0.1])
            z = GaussianDetection(rng.standard_normal((4, 1)), A, timestamp=t,
                                  measurement_model=LinearGaussian(4, [0, 1, 2, 3], A))
        h = SingleHypothesis(prediction, z, measurement_prediction=updater.predict_measurement(
            prediction, z.measurement_model))
        state = updater.update(h)
        assert np.all(np.isfinite(state.covar))
        assert (getattr(state, "fusion", None) is not None) == (k % 2 == 0)


@pytest.mark.parametrize("seed", range(3))
def test_the_reducer_weights(seed):
    rng = np.random.default_rng(seed)
    states = [GaussianState(rng.standard_normal((3, 1)), spd(rng, 3)) for _ in range(3)]
    optimal = NmciCovarianceIntersection().merge_components(*states)
    equal = CovarianceIntersection.merge_components(*states)
    assert np.trace(optimal.covar) <= np.trace(equal.covar) * (1 + 1e-12)
    given = NmciCovarianceIntersection().merge_components(*states, weights=[1, 2, 3])
    stone = CovarianceIntersection.merge_components(*states, weights=[1, 2, 3])
    assert np.allclose(given.covar, stone.covar, rtol=1e-12) and np.allclose(given.state_vector, stone.state_vector)
    assert sum(optimal.fusion.omega) == pytest.approx(1.0)


def test_fuse_tracks_at_common_times():
    rng = np.random.default_rng(2)
    times = [T0 + datetime.timedelta(seconds=s) for s in range(5)]
    one = Track([GaussianState(rng.standard_normal((2, 1)), spd(rng, 2), timestamp=t) for t in times])
    two = Track([GaussianState(rng.standard_normal((2, 1)), spd(rng, 2), timestamp=t) for t in times[2:]])
    fused = fuse_tracks([one, two])
    assert [s.timestamp for s in fused] == times[2:]
    for s, a, b in zip(fused, one.states[2:], two.states):
        assert np.trace(s.covar) <= min(np.trace(a.covar), np.trace(b.covar)) * (1 + 1e-12)


def test_blocks_from_transition_models():
    cv = ConstantVelocity(0.1)
    assert blocks_from_transition_model(CombinedLinearGaussianTransitionModel([cv, cv])) == [[0, 1], [2, 3]]
    assert blocks_from_transition_model(CombinedLinearGaussianTransitionModel([RandomWalk(1.0), cv])) == [[0], [1, 2]]
    assert blocks_from_transition_model(cv) == [[0, 1]]


@pytest.mark.parametrize("kwargs, field", [
    ({"rule": "kalman"}, "rule"),
    ({"rule": "nmci", "omega": 0.5}, "omega"),
    ({"omega": 1.5}, "omega"),
    ({"omega": True}, "omega"),
])
def test_bad_properties_are_refused_with_their_field(kwargs, field):
    with pytest.raises(nmci.RequestError) as e:
        NmciUpdater(measurement_model=None, **kwargs)
    assert e.value.field == field


def test_bad_input_is_refused_with_its_field():
    h = hypothesis(np.zeros(2), np.eye(2), np.zeros(2), np.eye(2))
    partial = LinearGaussian(ndim_state=2, mapping=(0,), noise_covar=np.eye(1))
    with pytest.raises(nmci.InputError) as e:
        NmciUpdater(measurement_model=None).predict_measurement(h.prediction, partial)
    assert e.value.field == "measurement_model"
    with pytest.raises(nmci.InputError) as e:
        NmciUpdater(measurement_model=None).update(hypothesis(np.zeros(2), -np.eye(2), np.zeros(2), np.eye(2)))
    assert e.value.field == "pa"
    with pytest.raises(nmci.RequestError) as e:
        NmciCovarianceIntersection().merge_components(GaussianState(np.zeros((1, 1)), np.eye(1)), weights=[-1])
    assert e.value.field == "weights"
    with pytest.raises(nmci.RequestError) as e:
        NmciCovarianceIntersection(rule="sdp")
    assert e.value.field == "rule"


def test_the_readme_switch_runs():
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    start = text.index("```python\nfrom nmci.stonesoup") + len("```python\n")
    block = text[start: text.index("```", start)]
    assert len(block.strip().splitlines()) == 3
    namespace = {"transition_model": CombinedLinearGaussianTransitionModel([ConstantVelocity(0.1)] * 2)}
    exec(compile(block, "README.md", "exec"), namespace)
    assert isinstance(namespace["track_updater"], NmciUpdater)
    assert namespace["track_updater"].blocks == [[0, 1], [2, 3]]


@pytest.mark.parametrize("A", [
    np.diag([1e-24, 1e-24, 0.5, 0.2]),      # a collapsed particle cloud in one block
    np.diag([1.0, 0.0, 0.5, 0.2]),          # a state claimed exactly
    np.full((4, 4), 0.04),                  # a broadcast row: rank one
])
@pytest.mark.parametrize("kwargs", [{}, {"rule": "nmci", "blocks": [[0, 1], [2, 3]]}, {"omega": 0.5},
                                    {"rule": "ici"}, {"rule": "ei"}])
def test_degenerate_covariances_do_not_stop_the_tracker(A, kwargs):
    """Semi-definite measurement covariances: the pseudo-inverse form (docs/methods.md,
    "Semi-definite covariances"), conservative: the update's covariance dominates its gains'
    error covariance for a sampled cross-covariance, and a claim of certainty is never trusted."""
    rng = np.random.default_rng(3)
    B = spd(rng, 4, [[0, 1], [2, 3]]) + np.eye(4)
    a, b = rng.standard_normal(4), rng.standard_normal(4)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", nmci.StructureWarning)
        update = NmciUpdater(measurement_model=None, **kwargs).update(hypothesis(a, A, b, B))
    P = np.asarray(update.covar, dtype=float)
    assert np.all(np.isfinite(P)) and np.linalg.eigvalsh((P + P.T) / 2).min() > 0
    # A direction the measurement claims exactly (a zero eigenvalue: not positive definite)
    # gets no information from it: the variance there is at least what the prediction's
    # information alone gives, 1 / (uᵀ B⁻¹ u). (The collapsed cloud is positive definite, and
    # its tiny variances are taken as given.)
    eigenvalues, vectors = np.linalg.eigh(A)
    if eigenvalues[0] <= 0.0:
        u = vectors[:, :1]
        assert (u.T @ P @ u).item() >= (1 - 1e-9) / (u.T @ np.linalg.inv(B) @ u).item()


def test_semidefinite_covariances_through_the_rule_functions_say_so():
    with pytest.warns(nmci.StructureWarning, match="pseudo-inverse form"):
        f = nmci.ci(np.diag([1.0, 0.0]), np.diag([2.0, 3.0]), np.array([1.0, 2.0]), np.zeros(2))
    assert abs(f.x[1]) <= 1e-12 and f.P[1, 1] >= 3.0 * (1 - 1e-12)
    # EI in the same form: state 0 the more informed a's, state 1 b's alone.
    with pytest.warns(nmci.StructureWarning, match="pseudo-inverse form"):
        f = nmci.ei(np.diag([1.0, 0.0]), np.diag([2.0, 3.0]), np.array([1.0, 2.0]), np.zeros(2))
    assert f.method == "ei" and np.allclose(f.P, np.diag([1.0, 3.0]), rtol=0, atol=1e-12)
    assert np.allclose(f.x, [1.0, 0.0], rtol=0, atol=1e-12)
    # ICI falls back to CI's form, and says so: the response is CI's.
    with pytest.warns(nmci.StructureWarning, match="ici has no pseudo-inverse form"):
        f = nmci.ici(np.diag([1.0, 0.0]), np.diag([2.0, 3.0]))
    assert f.method == "ci" and f.guarantee == "conservative"
    with pytest.warns(nmci.StructureWarning):
        g = nmci.ci(np.diag([1.0, 0.0]), np.diag([2.0, 3.0]))
    assert np.array_equal(f.P, g.P)
    # In a stack such a pair is the single call's.
    with pytest.warns(nmci.StructureWarning, match="pseudo-inverse form"):
        s = nmci.ci(np.stack([np.diag([1.0, 0.0]), np.eye(2)]), np.stack([np.diag([2.0, 3.0]), 2 * np.eye(2)]))
    assert np.array_equal(s.P[0], g.P)
    with pytest.raises(nmci.InputError) as e:
        nmci.certified(np.diag([1.0, 0.0]), np.diag([2.0, 3.0]))
    assert e.value.field == "pa"


def test_the_arguments_are_in_chernoff_updaters_order_and_checked_when_set():
    u = NmciUpdater(None, 0.3)
    assert u.omega == 0.3 and u.rule == "ci" and u.criterion == "trace" and u.on_violation == "merge"
    for name, value in [("omega", 1.7), ("omega", True), ("rule", "kalman"), ("criterion", "det"),
                        ("on_violation", "ignore"), ("coupling_tol", 2.0)]:
        with pytest.raises(nmci.RequestError) as e:
            setattr(u, name, value)
        assert e.value.field == name
    assert u.omega == 0.3  # a refused value leaves the property as it was
    with pytest.raises(nmci.RequestError) as e:
        u.rule = "nmci"  # a fixed omega is CI's
    assert e.value.field == "omega"
    u.omega = None
    u.rule = "nmci"
    assert u.rule == "nmci"


@pytest.mark.parametrize("on_violation", ["merge", "raise"])
def test_declared_blocks_the_data_violate_are_merged_or_refused(on_violation):
    rng = np.random.default_rng(8)
    A, B = spd(rng, 4), spd(rng, 4)  # every entry couples the axes, as a range-bearing radar's
    a, b = rng.standard_normal(4), rng.standard_normal(4)
    u = NmciUpdater(None, rule="nmci", blocks=[[0, 1], [2, 3]], on_violation=on_violation)
    if on_violation == "raise":
        with pytest.raises(nmci.InputError):
            u.update(hypothesis(a, A, b, B))
        return
    with pytest.warns(nmci.StructureWarning, match="couples declared blocks"):
        update = u.update(hypothesis(a, A, b, B))
    assert update.fusion.merged and update.fusion.blocks == ((0, 1, 2, 3),)
    # CI over the merged block: the same bound as CI on the whole state.
    ci = NmciUpdater(None, rule="ci").update(hypothesis(a, A, b, B))
    assert np.allclose(update.covar, ci.covar, rtol=1e-12, atol=1e-14)


def test_stone_soups_reducer_calls_work_on_the_class_and_ties_average():
    one = GaussianState(np.array([[1.0], [2.0]]), np.diag([2.0, 3.0]))
    two = GaussianState(np.array([[-1.0], [0.0]]), np.diag([2.0, 3.0]))
    assert NmciCovarianceIntersection.merge_components(one) is one
    merged = NmciCovarianceIntersection.merge_components(one, two)
    # Equal covariances: every weight is optimal; the middle one averages the means.
    assert np.allclose(merged.state_vector, [[0.0], [1.0]], atol=1e-12)
    assert merged.fusion.omega == pytest.approx((0.5, 0.5))
    equal = NmciCovarianceIntersection(weighting="equal").merge_components(one, two)
    stone = CovarianceIntersection.merge_components(one, two)
    assert np.array_equal(equal.covar, stone.covar) and np.array_equal(equal.state_vector, stone.state_vector)


def test_ties_average_the_means_in_ci_and_nmci():
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    a, b = np.array([1.0, 2.0]), np.array([3.0, -2.0])
    for f in (nmci.ci(P, P, a, b), nmci.nmci(P, P, a, b, pab_unknown=np.eye(2, dtype=bool))):
        assert np.allclose(f.x, (a + b) / 2, atol=1e-12) and np.allclose(f.omega, 0.5)


def test_fuse_tracks_with_a_predictor_aligns_the_times_and_says_what_it_left_out():
    from stonesoup.predictor.kalman import KalmanPredictor

    rng = np.random.default_rng(4)
    half = datetime.timedelta(seconds=0.5)
    one = Track([GaussianState(rng.standard_normal((2, 1)), spd(rng, 2), timestamp=T0 + 2 * k * half)
                 for k in range(3)])
    two = Track([GaussianState(rng.standard_normal((2, 1)), spd(rng, 2), timestamp=T0 + (2 * k + 1) * half)
                 for k in range(3)])
    with pytest.warns(UserWarning, match="6 of 6 times left out"):
        assert len(fuse_tracks([one, two])) == 0
    predictor = KalmanPredictor(ConstantVelocity(0.1))
    with pytest.warns(UserWarning, match="1 of 6 times left out"):
        fused = fuse_tracks([one, two], predictor=predictor)
    assert [s.timestamp for s in fused] == [T0 + k * half for k in range(1, 6)]


def test_ties_in_n_way_ci_take_the_centre_of_the_simplex():
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    xs = [np.array([1.0, 2.0]), np.array([3.0, -2.0]), np.array([-1.0, 3.0])]
    f = nmci.ci_nway([(x, P) for x in xs])
    assert np.allclose(np.ravel(f["weights"]), 1 / 3) and np.allclose(f.x, np.mean(xs, axis=0), atol=1e-12)
