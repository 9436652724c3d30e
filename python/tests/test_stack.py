"""Stacks: ``k`` pairs fused in one call, each pair's numbers those of the single call."""

import numpy as np
import pytest

import nmci


def spd(rng, n, k):
    a = rng.standard_normal((k, n, n))
    return a @ a.transpose(0, 2, 1) + n * np.eye(n)


@pytest.mark.parametrize("rule", ["ci", "nmci", "ici", "ei", "naive"])
@pytest.mark.parametrize("n", [1, 2, 4])
def test_each_pair_of_a_stack_is_the_single_call_bit_for_bit(rule, n):
    rng = np.random.default_rng(n)
    k = 25
    pa, pb = spd(rng, n, k), spd(rng, n, k)
    xa, xb = rng.standard_normal((k, n)), rng.standard_normal((k, n))
    pattern = rng.random((k, n, n)) < 0.6
    pattern |= np.eye(n, dtype=bool)
    call = getattr(nmci, rule)
    stack = call(pa, pb, xa, xb, pab_unknown=pattern)
    assert isinstance(stack, nmci.FusedStack) and len(stack) == k and stack.method == rule
    assert stack.P.shape == (k, n, n) and stack.x.shape == (k, n) and stack.trace.shape == (k,)
    for i in range(k):
        one = call(pa[i], pb[i], xa[i], xb[i], pab_unknown=pattern[i])
        assert np.array_equal(stack.x[i], one.x) and np.array_equal(stack.P[i], one.P)
        assert np.array_equal(stack.Ka[i], one.Ka) and np.array_equal(stack.Kb[i], one.Kb)
        assert stack.trace[i] == one.trace and stack.det[i] == one.det
        if one.omega is None:
            assert stack.omega is None
        elif rule == "nmci":
            assert stack.blocks[i] == one.blocks
            for block, w in zip(one.blocks, one.omega):
                assert np.all(stack.omega[i, block] == w)
        else:
            assert np.all(stack.omega[i] == one.omega[0])


def test_one_pattern_for_every_pair_and_the_paper_s_example():
    pa = np.array([np.diag([3.0, 1.0]), np.diag([1.0, 4.0])])
    pb = np.array([np.diag([1.0, 4.0]), np.diag([3.0, 1.0])])
    stack = nmci.nmci(pa, pb, pab_unknown=np.eye(2, dtype=bool))
    assert stack.trace.tolist() == [2.0, 2.0]
    assert stack.omega.tolist() == [[0.0, 1.0], [1.0, 0.0]]
    assert stack.blocks == [[[0], [1]], [[0], [1]]]
    empty = nmci.ci(np.zeros((0, 3, 3)), np.zeros((0, 3, 3)))
    assert len(empty) == 0 and empty.P.shape == (0, 3, 3)


def test_round_off_in_one_pair_is_absorbed_and_said_once():
    pa = np.array([np.diag([3.0, 1.0])] * 3)
    pa[1, 0, 1] = pa[1, 1, 0] = 1e-13
    pb = np.array([np.diag([1.0, 4.0])] * 3)
    with pytest.warns(nmci.StructureWarning, match=r"1 of 3 pairs \(the first, pair 1\)"):
        stack = nmci.nmci(pa, pb, blocks=[[0], [1]])
    assert stack.structure_notes[0] is None and stack.structure_notes[1] is not None
    assert stack.trace[1] > 2.0 and stack.trace[1] < 2.0 + 1e-9


@pytest.mark.parametrize(
    "call,error,field,needle",
    [
        (lambda a, b: nmci.ci(a, -b), nmci.InputError, "pb[0]", "pair 0: P_b is not positive definite"),
        (lambda a, b: nmci.ci(a, b[:3]), nmci.RequestError, "pb", "`pb` holds 27 numbers, expected 4 × 9"),
        (lambda a, b: nmci.ci(a, b, np.zeros((4, 2))), nmci.RequestError, "xa", "`xa` holds 8 numbers, expected 4 × 3"),
        (lambda a, b: nmci.ci(a, b, pab_unknown=np.ones((2, 3, 3), bool)), nmci.RequestError, "pab_unknown", "expected 9 (every pair's) or 4 × 9"),
        (lambda a, b: nmci.certified(a, b), nmci.RequestError, "method", "a stack takes ci, nmci, ici, ei or naive"),
        (lambda a, b: nmci.ci(a, b, criterion="volume"), nmci.RequestError, "criterion", "unknown variant `volume`"),
        (lambda a, b: nmci.nmci(a, b, blocks=[[0]]), nmci.InputError, "blocks", "pair 0: "),
        (lambda a, b: nmci.ci(a, b[:, :2, :2]), nmci.RequestError, "pb", "`pb` holds 16 numbers"),
        (lambda a, b: nmci.ci(a, b[0]), nmci.InputError, "pb", "P_b must be a 3-D array (got 2-D)"),
    ],
)
def test_stack_errors_name_the_pair_and_the_field(call, error, field, needle):
    rng = np.random.default_rng(0)
    a, b = spd(rng, 3, 4), spd(rng, 3, 4)
    with pytest.raises(error) as raised:
        call(a, b)
    assert needle in str(raised.value)
    assert raised.value.field == field


def test_a_bad_pair_in_the_middle_is_named():
    rng = np.random.default_rng(1)
    a, b = spd(rng, 2, 40), spd(rng, 2, 40)
    a[17] = -a[17]
    with pytest.raises(nmci.InputError) as raised:
        nmci.nmci(a, b)
    assert raised.value.field == "pa[17]" and str(raised.value).startswith("pair 17: P_a")


def test_the_contract_takes_a_list_of_requests():
    one = {"pa": [[3.0, 0.0], [0.0, 1.0]], "pb": [[1.0, 0.0], [0.0, 4.0]], "method": "ci"}
    assert nmci.fuse([one, one]) == [nmci.fuse(one)] * 2
    with pytest.raises(nmci.InputError) as raised:
        nmci.fuse([one, {**one, "pa": [[-1.0]], "pb": [[1.0]]}])
    assert raised.value.field == "[1].pa" and str(raised.value).startswith("request 1: P_a")
    with pytest.raises(nmci.RequestError) as raised:
        nmci.fuse([one, {**one, "pa": [[float("nan"), 0.0], [0.0, 1.0]]}])
    assert raised.value.field == "[1].pa" and "`[1].pa[0][0]` is NaN" in str(raised.value)
