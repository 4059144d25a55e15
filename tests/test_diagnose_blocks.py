"""The diagnosis scores all candidates at once from the diagonal blocks of C^T C; checked here against one plain
numpy least-squares call per candidate on its projected columns (what the selection did before, and the definition)."""
import numpy as np
import pytest

from calib.diagnose.select import _block_normal_equations, _diagonal_blocks


def _problem(seed: int):
    rng = np.random.default_rng(seed)
    m, nb = 400, 12
    B = rng.normal(size=(m, nb)) * 10.0 ** rng.uniform(-2, 2, nb)
    sizes = rng.integers(1, 5, 30)                                     # candidates of 1-4 columns
    C = rng.normal(size=(m, sizes.sum())) * 10.0 ** rng.uniform(-3, 3, sizes.sum())
    C += B @ rng.normal(size=(nb, sizes.sum())) * 0.5 * np.linalg.norm(C, axis=0) / np.linalg.norm(B, axis=0).mean()
    Q, _ = np.linalg.qr(B)
    r = rng.normal(size=m)
    r -= Q @ (Q.T @ r)
    return C, Q, r, np.cumsum(np.r_[0, sizes])[:-1], sizes


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_block_solutions_equal_one_lstsq_per_candidate(seed):
    C, Q, r, starts, sizes = _problem(seed)
    dc = _block_normal_equations(C, Q.T @ C, C.T @ r, starts)
    P = C - Q @ (Q.T @ C)
    for s, n in zip(starts, sizes):
        ref, *_ = np.linalg.lstsq(P[:, s: s + n], r, rcond=None)
        assert dc[s: s + n] == pytest.approx(ref, rel=1e-9, abs=1e-12 * np.abs(ref).max())


def test_diagonal_blocks_are_the_projected_gram_blocks():
    C, Q, _, starts, sizes = _problem(3)
    P = C - Q @ (Q.T @ C)
    seen = 0
    for first, G in _diagonal_blocks(C, Q.T @ C, starts):
        for s, g in zip(first, G):
            n = sizes[list(starts).index(s)]
            assert g.shape == (n, n)
            ref = P[:, s: s + n].T @ P[:, s: s + n]
            assert np.allclose(g, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
            seen += 1
    assert seen == len(starts)
