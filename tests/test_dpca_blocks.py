"""dpca/blocks.py (issue #30): the range-edge guard read from the records, and the yaw's mean with
a cut scaled to each block's predicted spread."""

from __future__ import annotations

import numpy as np
import pytest

from clsas.estimate.dpca.blocks import EDGE_PIECES, YAW_CUT, clear_of_range_edges, yaw_mean

BLOCK, WIDTH, N_BLOCKS = 64, 96, 40
NEAR, FAR = 700, 1900       # the seafloor's range edges, samples


def _records(rng, bright: int | None = None) -> np.ndarray:
    """(hydrophone, ping, block, sample): unit-power complex speckle over samples [NEAR, FAR),
    -40 dB outside (sidelobes, noise), 3 pings (2 pairs), 8 hydrophones with their own speckle;
    ``bright``: a block 30 dB above the seafloor."""
    n = N_BLOCKS * BLOCK
    level = np.where((np.arange(n) >= NEAR) & (np.arange(n) < FAR), 1.0, 1e-4)
    if bright is not None:
        level[bright * BLOCK:(bright + 1) * BLOCK] = 1e3
    x = (rng.standard_normal((8, 3, n)) + 1j * rng.standard_normal((8, 3, n))) * np.sqrt(level / 2)
    return x.reshape(8, 3, N_BLOCKS, BLOCK)


def _typical(data):
    energy = np.einsum("hpbk,hpbk->pb", data, np.conj(data)).real
    energy = energy[:-1] + energy[1:]
    return np.median(energy[:, NEAR // BLOCK + 1:FAR // BLOCK - 1], axis=1, keepdims=True)


def test_range_edges_from_the_records(rng):
    data = _records(rng)
    clear = clear_of_range_edges(data, WIDTH, _typical(data))
    assert clear.shape == (2, N_BLOCKS) and np.all(clear[0] == clear[1])
    lo = np.arange(N_BLOCKS) * BLOCK
    hi = lo + BLOCK
    piece = WIDTH / EDGE_PIECES
    # clear where the seafloor reaches WIDTH beyond the block both sides; out where a whole piece
    # of either window lies beyond an edge (between the two, within a piece: either)
    seafloor = (lo >= NEAR) & (hi <= FAR)
    assert np.all(clear[0][(lo - WIDTH >= NEAR) & (hi + WIDTH <= FAR)])
    assert not np.any(clear[0][seafloor & ((lo - WIDTH < NEAR - piece) | (hi + WIDTH > FAR + piece))])
    # (a block off the seafloor is judged against its own surroundings: the estimator's weak-block
    # rule leaves those out)
    # a bright block on the seafloor keeps its place (its level capped at the typical block's),
    # and so do its neighbours
    bright = _records(rng, bright=20)
    assert np.array_equal(clear_of_range_edges(bright, WIDTH, _typical(bright)), clear)


def test_range_edges_beyond_the_records(rng):
    """A block whose windows run past the records' ends is out (what lies there is not known),
    even on a seafloor that fills the record."""
    n = N_BLOCKS * BLOCK
    data = ((rng.standard_normal((4, 2, n)) + 1j * rng.standard_normal((4, 2, n))) / np.sqrt(2)).reshape(
        4, 2, N_BLOCKS, BLOCK)
    clear = clear_of_range_edges(data, WIDTH, np.full((1, 1), 8.0 * BLOCK))[0]
    lo = np.arange(N_BLOCKS) * BLOCK
    assert np.array_equal(clear, (lo - WIDTH >= 0) & (lo + BLOCK + WIDTH <= n))


def _blocks(rng, pairs=4000, n=8, kappa=300e-6, drift=3e-6):
    """Block yaws whose spread is kappa s and whose mean falls with s (odd about the blocks'
    mean s, zero over all of them), as on the motionless seafloors: s from rho in 0.990-0.9999."""
    rho = rng.uniform(0.990, 0.9999, (pairs, n))
    s = np.sqrt(1 - rho**2) / rho
    yaw = -drift * (s - np.mean(s)) / np.std(s) + kappa * s * rng.standard_normal((pairs, n))
    return yaw, rho, s


def test_yaw_mean_is_unbiased_where_the_weights_are_not(rng):
    yaw, rho, s = _blocks(rng)
    use = np.ones(yaw.shape, bool)
    mean, std, kept = yaw_mean(yaw, use, rho, use)
    err = np.std(mean) / np.sqrt(mean.size)
    assert abs(np.mean(mean)) < 4 * err
    # the reported standard error is the pair means' spread (kappa measured on the blocks)
    assert np.median(std) == pytest.approx(np.std(mean), rel=0.1)
    # Gaussian blocks are hardly ever cut
    assert kept.mean() > 0.999
    # weights 1 / s^2 prefer the coherent blocks, whose yaw reads high here: biased
    weighted, _, _ = yaw_mean(yaw, use, rho, use, weighted=True)
    assert np.mean(weighted) > 10 * err


def test_yaw_mean_cuts_outliers(rng):
    """An off-beam block (hundreds of urad) in every pair is cut; each pair's mean is that of its
    other blocks."""
    yaw, rho, s = _blocks(rng, pairs=200)
    yaw[:, 3] = -600e-6
    use = np.ones(yaw.shape, bool)
    mean, _, kept = yaw_mean(yaw, use, rho, use)
    assert not np.any(kept[:, 3]) and np.all(kept.sum(axis=1) >= 6)
    assert np.allclose(mean, np.sum(np.where(kept, yaw, 0), axis=1) / kept.sum(axis=1))
    assert np.all(np.abs(yaw - np.median(yaw, axis=1, keepdims=True))[kept] <= YAW_CUT * 2 * 300e-6 * s.max())


def test_yaw_mean_on_one_block_a_pair(rng, caplog):
    """One block a pair: its yaw, its spread measured on the spare blocks; with no spare either,
    the standard error is NaN (not known) and a warning says why."""
    yaw, rho, _ = _blocks(rng, pairs=50)
    one = np.zeros(yaw.shape, bool)
    one[:, 2] = True
    mean, std, _ = yaw_mean(yaw, one, rho, np.ones(yaw.shape, bool))
    assert np.array_equal(mean, yaw[:, 2]) and np.all(np.isfinite(std) & (std > 0))
    with caplog.at_level("WARNING", logger="clsas"):
        _, std, _ = yaw_mean(yaw, one, rho, one)
    assert np.all(np.isnan(std)) and "yaw_std is NaN" in caplog.text
