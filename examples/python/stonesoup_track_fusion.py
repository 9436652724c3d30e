"""Track-to-track fusion in Stone Soup: ChernoffUpdater (ω = 0.5) against nmci's NmciUpdater with
CI and with nmCI, over Monte Carlo runs.

One target moves with a constant-velocity model on each axis
(``CombinedLinearGaussianTransitionModel``). Two sensors measure its position with axis-aligned
noise of different shapes; each runs its own Kalman filter (a local track). At every step a fusion
centre fuses the two local tracks' current states — sensor 1's as a ``GaussianDetection``, as
``Tracks2GaussianDetectionFeeder`` makes it, sensor 2's as the prediction — without feeding the
result back. The local errors are correlated by the common process noise, by an unknown amount:
hence CI. The axes never mix (model, sensors, filters), so the cross-covariance is zero between
the x-states and the y-states: the blocks of ``blocks_from_transition_model``, which nmCI uses.

Reported per rule, over the runs and the steps after the first five: position RMSE, the mean
NEES of the 4-state estimate (at most 4 on average for a conservative bound) and the mean trace
of the bound. Whatever the numbers are, they are printed; nothing is asserted about who wins.

    python examples/python/stonesoup_track_fusion.py [--quick]
"""

import datetime
import sys

import numpy as np
from stonesoup.models.measurement.linear import LinearGaussian
from stonesoup.models.transition.linear import CombinedLinearGaussianTransitionModel, ConstantVelocity
from stonesoup.predictor.kalman import KalmanPredictor
from stonesoup.types.detection import Detection, GaussianDetection
from stonesoup.types.groundtruth import GroundTruthState
from stonesoup.types.hypothesis import SingleHypothesis
from stonesoup.types.prediction import GaussianStatePrediction
from stonesoup.types.state import GaussianState
from stonesoup.updater.chernoff import ChernoffUpdater
from stonesoup.updater.kalman import KalmanUpdater

from nmci.stonesoup import NmciUpdater, blocks_from_transition_model

quick = "--quick" in sys.argv
runs, steps = (3, 20) if quick else (100, 60)
start = datetime.datetime(2026, 1, 1)
dt = datetime.timedelta(seconds=1)

transition = CombinedLinearGaussianTransitionModel([ConstantVelocity(0.05), ConstantVelocity(0.05)])
blocks = blocks_from_transition_model(transition)  # [[0, 1], [2, 3]]
sensors = [
    LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([4.0, 0.25])),
    LinearGaussian(ndim_state=4, mapping=(0, 2), noise_covar=np.diag([0.25, 4.0])),
]
predictor = KalmanPredictor(transition)
local_updaters = [KalmanUpdater(s) for s in sensors]
fusers = {
    "ChernoffUpdater (ω = 0.5)": ChernoffUpdater(measurement_model=None, omega=0.5),
    "NmciUpdater, CI": NmciUpdater(measurement_model=None, rule="ci"),
    "NmciUpdater, nmCI (per-axis ω)": NmciUpdater(measurement_model=None, rule="nmci", blocks=blocks),
}
names = ["local track, sensor 1", "local track, sensor 2", *fusers]
errors = {name: [] for name in names}  # (position error², NEES, trace) per run and step

rng = np.random.default_rng(2026)
for run in range(runs):
    truth = GroundTruthState(np.array([[0.0], [1.0], [0.0], [0.5]]), timestamp=start)
    prior = GaussianState(truth.state_vector + rng.normal(0, 1, (4, 1)), np.diag([1.0, 0.5, 1.0, 0.5]),
                          timestamp=start)
    local = [prior, prior]
    for k in range(1, steps + 1):
        t = start + k * dt
        truth = GroundTruthState(transition.function(truth, noise=True, time_interval=dt), timestamp=t)
        for i, (sensor, updater) in enumerate(zip(sensors, local_updaters)):
            z = Detection(sensor.function(truth, noise=True), timestamp=t, measurement_model=sensor)
            local[i] = updater.update(SingleHypothesis(predictor.predict(local[i], timestamp=t), z))
        track_1 = GaussianDetection(local[0].state_vector, local[0].covar, timestamp=t,
                                    measurement_model=LinearGaussian(4, [0, 1, 2, 3], local[0].covar))
        track_2 = GaussianStatePrediction(local[1].state_vector, local[1].covar, timestamp=t)
        estimates = dict(zip(names, local))
        for name, fuser in fusers.items():
            estimates[name] = fuser.update(SingleHypothesis(track_2, track_1))
        if k <= 5:
            continue
        for name, estimate in estimates.items():
            e = np.asarray(estimate.state_vector - truth.state_vector, dtype=float).ravel()
            P = np.asarray(estimate.covar, dtype=float)
            errors[name].append((e[0] ** 2 + e[2] ** 2, e @ np.linalg.solve(P, e), np.trace(P)))

print(f"{runs} runs × {steps - 5} steps; NEES of the 4-state estimate (≤ 4 on average: conservative)")
print()
print("| estimate | position RMSE | mean NEES | mean tr P |")
print("|---|---|---|---|")
for name in names:
    sq, nees, trace = np.array(errors[name]).T
    print(f"| {name} | {np.sqrt(sq.mean()):.3f} | {nees.mean():.2f} | {trace.mean():.3f} |")
