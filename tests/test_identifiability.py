"""The identifiability analysis against a plain numpy full SVD of an independent, rank-deficient matrix.

Why: ``calib.identifiability.analyse`` decomposes a small factor of the Jacobian (one QR, then SVDs of R) instead of
the Jacobian itself; these tests build a matrix whose dependencies are known by construction (an exact pair, an exact
triple, a column with no effect, a practically dependent pair, a weakly determined pair) and check every figure
against ``np.linalg.svd`` of the column-scaled matrix, written here again in full.
"""
import numpy as np
import pytest

from calib.identifiability import HOLD_RTOL, RANK_RTOL, WEAK_RTOL, analyse

NAMES = [f"p{i}" for i in range(14)]


def dependent_matrix(m: int = 300, seed: int = 0) -> np.ndarray:
    """Columns 0-9 random with scales over six decades; 10 = 2.5 * 3 (pair), 11 = 1 - 0.5 * 6 (triple), 12 = 0 (no
    effect), 13 = 8 + 1e-6 noise (practically undeterminable), 9 = 5 + 3e-3 noise (weakly determined)."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(m, 14)) * 10.0 ** rng.uniform(-3, 3, 14)
    J[:, 10] = 2.5 * J[:, 3]
    J[:, 11] = J[:, 1] - 0.5 * J[:, 6]
    J[:, 12] = 0.0
    J[:, 13] = J[:, 8] + 1e-6 * np.linalg.norm(J[:, 8]) / np.sqrt(m) * rng.normal(size=m)
    J[:, 9] = J[:, 5] + 3e-3 * np.linalg.norm(J[:, 5]) / np.sqrt(m) * rng.normal(size=m)
    return J


def scaled(J: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(J, axis=0)
    return J / np.where(n > 0, n, 1.0)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_rank_condition_and_holds_match_a_plain_full_svd(seed):
    J = dependent_matrix(seed=seed)
    out = analyse(J, NAMES)
    Js = scaled(J)
    s = np.linalg.svd(Js, compute_uv=False)
    assert np.allclose(out.singular_values, s, rtol=0, atol=1e-10 * s[0])
    assert out.rank == int(np.sum(s / s[0] > RANK_RTOL)) == 11          # pair, triple and empty column
    assert out.condition == np.inf
    # one parameter held per dependency, and the rest full rank by the plain SVD, with the same condition
    held = {NAMES.index(n) for n in out.fixed}
    assert len(held) == 4 and 12 in held
    assert len(held & {3, 10}) == len(held & {1, 6, 11}) == len(held & {8, 13}) == 1
    kept = [NAMES.index(n) for n in out.kept]
    assert sorted(kept + sorted(held)) == list(range(14))
    s_k = np.linalg.svd(Js[:, kept], compute_uv=False)
    assert s_k[-1] / s[0] > HOLD_RTOL
    assert out.kept_condition == pytest.approx(s_k[0] / s_k[-1], rel=1e-8)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_combinations_match_the_plain_svd_vectors(seed):
    J = dependent_matrix(seed=seed)
    out = analyse(J, NAMES)
    Js = scaled(J)
    smax = np.linalg.svd(Js, compute_uv=False)[0]
    # each undeterminable combination is the null space written with unit on its held parameter, zero on the other
    # held ones (any basis of the directions below HOLD_RTOL gives the same), and its ratio |Js v| / |v|
    _, s, Vt = np.linalg.svd(Js)
    null = Vt[s / smax <= HOLD_RTOL].T
    held = [NAMES.index(n) for n in out.fixed]
    basis = null @ np.linalg.inv(null[held, :])
    assert len(out.unidentifiable) == len(held) == 4
    for c, b in zip(out.unidentifiable, basis.T):
        want = {NAMES[k]: b[k] for k in np.flatnonzero(np.abs(b) > 0.05)}
        assert set(c.coefficients) == set(want)
        assert [c.coefficients[n] for n in want] == pytest.approx(list(want.values()), abs=1e-6)
        assert c.ratio == pytest.approx(np.linalg.norm(Js @ b) / np.linalg.norm(b) / smax, rel=1e-3, abs=1e-12)
    # the three weakest kept directions are the plain SVD's last right vectors of the kept columns, sign fixed
    kept = [NAMES.index(n) for n in out.kept]
    _, s_k, Vt = np.linalg.svd(Js[:, kept], full_matrices=False)
    assert [c.ratio for c in out.weakest] == pytest.approx(list(s_k[::-1][:3] / smax), rel=1e-8)
    for c, ref in zip(out.weakest, Vt[::-1][:3]):
        ref = ref * np.sign(ref[np.argmax(np.abs(ref))])          # largest coefficient positive
        want = {out.kept[i]: ref[i] for i in np.flatnonzero(np.abs(ref) > 0.05)}
        assert set(c.coefficients) == set(want)
        assert [c.coefficients[n] for n in want] == pytest.approx(list(want.values()), abs=1e-8)
        assert max(c.coefficients.values(), key=abs) > 0
    # the 5/9 pair is determined, weakly: reported as such, both named
    weak = [c for c in out.weak if {"p5", "p9"} <= set(c.coefficients)]
    assert len(weak) == 1 and weak[0].ratio < WEAK_RTOL
    assert "p5" in weak[0].words() and "p9" in weak[0].words()


def test_report_does_not_depend_on_the_row_order():
    """A multi-dimensional null space has no preferred basis: what is held and printed must not follow rounding."""
    J = dependent_matrix(seed=3)
    rng = np.random.default_rng(7)
    ref = analyse(J, NAMES)
    for _ in range(5):
        again = analyse(J[rng.permutation(len(J))], NAMES)
        assert again.report() == ref.report()
        assert [c.words() for c in again.weakest] == [c.words() for c in ref.weakest]


def test_fewer_rows_than_parameters():
    J = dependent_matrix(m=8, seed=4)
    out = analyse(J, NAMES)
    s = np.linalg.svd(scaled(J), compute_uv=False)
    assert out.rank == int(np.sum(s / s[0] > RANK_RTOL)) <= 8
    kept = [NAMES.index(n) for n in out.kept]
    s_k = np.linalg.svd(scaled(J)[:, kept], compute_uv=False)
    assert len(kept) <= 8 and s_k[-1] / s[0] > HOLD_RTOL
    assert out.kept_condition == pytest.approx(s_k[0] / s_k[-1], rel=1e-8)


def many_nulls_matrix(m: int = 400, seed: int = 0) -> tuple[np.ndarray, list[str]]:
    """Eight random columns over six decades, then seven exact combinations of them (pairs, a triple, a chain through
    another combination): seven exactly undeterminable directions at once, as a tree's geometry has (14 there)."""
    rng = np.random.default_rng(seed)
    B = rng.normal(size=(m, 8)) * 10.0 ** rng.uniform(-3, 3, 8)
    extra = [3.0 * B[:, 0], B[:, 1] - 2.0 * B[:, 2], -B[:, 3], B[:, 4] + B[:, 5] + B[:, 6], 0.5 * B[:, 7],
             B[:, 0] + 4.0 * B[:, 7], 1e3 * B[:, 2]]
    J = np.column_stack([B] + extra)
    order = rng.permutation(J.shape[1])
    return J[:, order], [f"q{i}" for i in order]


def _held_one_by_one(J: np.ndarray, names: list[str]) -> list[str]:
    """The hold rule with a fresh full SVD of the plain column-scaled matrix after every held parameter (no small
    factor, no null space carried over): the largest weight on the exact null space, ties to the first name."""
    Js = scaled(J)
    keep, held = list(range(J.shape[1])), []
    while True:
        _, s, Vt = np.linalg.svd(Js[:, keep], full_matrices=False)
        ratio = s / s[0]
        rank = int(np.sum(ratio > RANK_RTOL))
        if rank == len(keep) and ratio[-1] > HOLD_RTOL:
            return held
        null = Vt[rank:] if rank < len(keep) else Vt[-1:]
        w = np.linalg.norm(null, axis=0)
        top = max(w[k] for k in range(len(keep)) if w[k] > 0.2 * w.max())
        k = min(k for k in range(len(keep)) if w[k] > 0.2 * w.max() and w[k] >= top * (1.0 - 1e-6))
        held.append(names[keep.pop(k)])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_several_exact_nulls_held_as_one_decomposition_per_parameter_holds(seed):
    # analyse follows the exact null space from held parameter to held parameter instead of decomposing again: the
    # held set must be the one a decomposition after every held parameter gives
    J, names = many_nulls_matrix(seed=seed)
    out = analyse(J, names)
    assert out.fixed == _held_one_by_one(J, names)
    assert len(out.fixed) == 7
    s_k = np.linalg.svd(scaled(J)[:, [names.index(n) for n in out.kept]], compute_uv=False)
    assert s_k[-1] / s_k[0] > HOLD_RTOL
