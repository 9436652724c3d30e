"""Structure that survives round-off, from Python: declared ``blocks``, near-zero couplings
absorbed (``coupling_tol``), the response's ``structure`` and its note as a
``StructureWarning``; the same numbers as the contract."""

import warnings

import numpy as np
import pytest

import nmci

PA = np.array([[3.0, 1e-13], [1e-13, 1.0]])
PB = np.diag([1.0, 4.0])
DIAGONAL = np.eye(2, dtype=bool)


@pytest.mark.parametrize("rule", [nmci.nmci, nmci.certified])
def test_a_round_off_coupling_keeps_the_blocks_and_says_so(rule):
    with pytest.warns(nmci.StructureWarning, match="absorbed"):
        r = rule(PA, PB, pab_unknown=DIAGONAL)
    assert r.structure["blocks"] == [[0], [1]]
    assert r.structure["exact_blocks"] == 1
    assert r.structure_note == r.structure["note"]
    assert abs(r.trace - 2.0) < 1e-9
    # CI on the same covariances gives more.
    assert nmci.ci(PA, PB).trace > 3.0


STACK_A = np.array([PA, np.diag([3.0, 1.0])])
STACK_B = np.array([PB, PB])


@pytest.mark.parametrize(
    "call",
    [
        lambda: nmci.nmci(PA, PB, pab_unknown=DIAGONAL),  # the arrays as they are
        lambda: nmci.nmci(PA.tolist(), PB, pab_unknown=DIAGONAL),  # converted first
        lambda: nmci.nmci(PA, PB, blocks=[[0], [1]]),
        lambda: nmci.certified(PA, PB, pab_unknown=DIAGONAL),
        lambda: nmci.nmci(STACK_A, STACK_B, blocks=[[0], [1]]),  # a stack: one warning
        lambda: nmci.nmci_nway([PA, PB], blocks=[[0], [1]]),
    ],
)
def test_the_warning_points_at_the_users_line(call):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        call()
    assert [w.category for w in caught] == [nmci.StructureWarning]
    assert caught[0].filename == __file__


def test_exact_zeros_say_nothing_and_are_unchanged():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = nmci.nmci(PB, np.diag([3.0, 1.0]), pab_unknown=DIAGONAL)
    assert r.structure is None and r.structure_note is None
    assert np.array_equal(r.P, np.eye(2))


def test_declared_blocks_imply_the_pattern():
    with pytest.warns(nmci.StructureWarning):
        declared = nmci.nmci(PA, PB, blocks=[[0], [1]])
    with pytest.warns(nmci.StructureWarning):
        patterned = nmci.nmci(PA, PB, pab_unknown=DIAGONAL)
    assert np.array_equal(declared.P, patterned.P)
    assert declared.to_dict()["structure"] == nmci.fuse(
        {"pa": PA, "pb": PB, "blocks": [[0], [1]], "method": "nmci"}
    )["structure"]


def test_without_absorption_nmci_is_ci_and_the_note_says_how_to_keep_the_blocks():
    with pytest.warns(nmci.StructureWarning, match="keeps blocks merged"):
        strict = nmci.nmci(PA, PB, pab_unknown=DIAGONAL, coupling_tol=0.0)
    assert abs(strict.trace - nmci.ci(PA, PB).trace) < 1e-12


def test_the_sdp_keeps_the_blocks_and_the_cutting_planes_say_why_they_do_not():
    with pytest.warns(nmci.StructureWarning, match="diagonal lowered"):
        r = nmci.optimal(PA, PB, pab_unknown=DIAGONAL, samples=50)
    assert r.structure["absorbed"] is True and r.blocks == [[0], [1]]
    assert r.lower_bound <= r.upper_bound
    with pytest.warns(nmci.StructureWarning, match="not absorbed"):
        cuts = nmci.sdp_cuts(PA, PB, pab_unknown=DIAGONAL)
    assert cuts.structure["absorbed"] is False


def test_n_way_nmci_takes_declared_blocks():
    with pytest.warns(nmci.StructureWarning):
        r = nmci.nmci_nway([PA, PB, np.diag([2.0, 2.0])], blocks=[[0], [1]])
    assert r.blocks == [[0], [1]]
    assert r.structure["couplings"][0]["matrix"] == "estimates[0].p"


@pytest.mark.parametrize(
    "kwargs,field,needle",
    [
        ({"Pa": [[2, 0.5], [0.5, 1]], "blocks": [[0], [1]]}, "pa", "pa[0][1] = 0.5 couples blocks 0 and 1"),
        ({"blocks": [[0, 1], [1]]}, "blocks", "state 1 is in two blocks"),
        ({"blocks": [[0]]}, "blocks", "state 1 is in no block"),
        ({"blocks": [[0], [1]], "pab_unknown": np.ones((2, 2), bool)}, "pab_unknown", "pab_unknown[0][1]"),
        ({"coupling_tol": -1.0}, "coupling_tol", "coupling_tol must be in [0, 1]"),
        ({"coupling_tol": float("nan")}, "coupling_tol", "coupling_tol must be in [0, 1] (got NaN)"),
    ],
)
def test_refusals_name_their_field(kwargs, field, needle):
    args = {"Pa": np.eye(2), "Pb": np.eye(2), **kwargs}
    with pytest.raises(nmci.NmciError) as raised:
        nmci.nmci(args.pop("Pa"), args.pop("Pb"), **args)
    assert raised.value.field == field
    assert needle in str(raised.value)


@pytest.mark.parametrize("rule", ["nmci", "certified", "optimal", "sdp_cuts"])
def test_each_rules_docstring_says_what_it_does_with_couplings(rule):
    """The docstring's claim about absorption is the response's ``absorbed`` field."""
    f = getattr(nmci, rule)
    doc = " ".join(f.__doc__.split())
    says_not = "not absorbed" in doc or "*not* absorbed" in doc
    says_absorbed = "are absorbed" in doc or "(``absorbed``: ``True``)" in doc
    assert says_not != says_absorbed, doc
    Pa = np.array([[3.0, 1e-12], [1e-12, 1.0]])
    Pb = np.diag([1.0, 4.0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        kwargs = {"samples": 50} if rule == "optimal" else {}
        r = f(Pa, Pb, blocks=[[0], [1]], **kwargs)
    assert r.structure["absorbed"] is says_absorbed, (rule, r.structure)
