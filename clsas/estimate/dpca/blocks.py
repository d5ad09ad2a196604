"""Which range blocks a ping pair's yaw is read from, and how their yaws are combined (issue #30).

Two rules, each derived from what biased the yaw on a motionless platform (tests/test_dpca_bias.py).

The range-edge guard (:func:`clear_of_range_edges`)
---------------------------------------------------
A compressed pulse of length T has range sidelobes out to c T / 2 either side of its
scatterer (the matched filter's support), and a block's correlation holds, besides its own
scatterers' main lobes, the sidelobes of every scatterer within c T / 2 of it. Those carry a
yaw error odd in the offset of the sample from its scatterer (the phase-centre carrier
correction is applied at the sample's range, not the scatterer's; a chirp sampled little above
its band folds its skirt into a flat pedestal out to c T / 2: geometry.inside_swath has the
measurements): where the seafloor's echo is about even in range they cancel, within c T / 2 of
the seafloor's near or far range edge they come from one side only and bias the block's yaw
(near edge negative, far edge positive). So a block enters the yaw only where the seafloor
reaches c T / 2 beyond it on both sides. Where the seafloor reaches is read from the records,
not from a model of the scene (so that the rule holds for any seafloor extent, and for
recorded data): the pair's echo energy a sample, summed over its hydrophones and both pings, is
averaged over EDGE_PIECES equal pieces of the c T / 2 before the block and of the c T / 2 after
it, and every piece must hold at least EDGE_LEVEL of the block's own energy a sample. The
seafloor's echo steps down at its range edge within the compressed pulse's main lobe (c / 2B)
by as much as its range sidelobes lie below it (20-25 dB on the bias scenes, about 0.5 m past
the edge), so a piece that lies beyond an edge, or reaches beyond it by more than nine tenths
of its length, reads far below EDGE_LEVEL (-10 dB), while a piece on the seafloor averages
B T / EDGE_PIECES resolution cells of speckle (about twelve for B T = 100: a mean of that many
exponential cells falls below a tenth of its expectation with a probability near 1e-6) and
leaves room for the seafloor's level to change by a factor of several within c T / 2. The
guard so found is c T / 2 to within an EDGE_PIECES-th of it. Blocks whose windows run past the
records' ends are left out too (what lies there is not known). A block holding a bright echo
is measured against the pair's typical block instead (its neighbours are seafloor; its own
sidelobes dominate the others' it holds).

The yaw's mean (:func:`yaw_mean`)
--------------------------------
A block's yaw error has a spread proportional to s = sqrt(1 - rho^2) / rho, rho the block's
beam peak (pass 2's coherence): the phase of a correlation at coherence rho over N samples has
variance (1 - rho^2) / (2 N rho^2), the same N in every block, and the yaw is the slope of
those phases along the couples, so its standard deviation is kappa s with one kappa for every
block of an echo (its constant, set by N, the couples' layout and how the couples' errors
correlate, is not predicted well from first principles; it is measured on the echo's own
blocks, below). Both the spread and the mean of a block's yaw depend on rho: blocks that hold
more of the seafloor's wide look angles decorrelate more and read a more negative yaw (the
per-scatterer phase-centre residual D (sin^2 theta - <sin^2 theta>) / r; it averages to zero
over the blocks, not over any subset chosen by rho). Hence:

- the mean is unweighted: weights 1 / s^2 (inverse variance, the least noisy mean under the
  model) prefer the coherent blocks and bias the yaw positive (with the c T / 2 guard, on 40
  seafloors 4x the footprint, seeds 100-139: +0.40 / +0.61 urad a pair for the 1x / 2x
  transmitter against the unweighted mean of the same blocks). estimate's yaw_rule
  "low-noise" takes them anyway, with the one-block guard, for short tracks;
- outliers (a block dominated by a lone bright echo, off-beam returns) are rejected by a cut
  scaled to each block's own predicted spread, |yaw - median| > YAW_CUT kappa s' (s'^2 = s^2
  plus the median's, pi / 2 sum s^2 / n^2 over the pair's n blocks), which takes
  the same fraction of every rho's blocks. A cut of one width for every block of a pair (the
  3-MAD trim used before) takes mostly the wide-spread, low-rho blocks, i.e. the negative
  ones: on the 4x seafloors that selection moved the mean by +0.33 urad.

kappa: first robustly, 1.4826 x the median of |yaw - median| / s' over every block of the echo
(the cut's scale), then, from the kept blocks, kappa^2 = sum ((yaw - pair mean) / s)^2 over its expectation
(n_pair - 1 a pair for equal s: _kappa has the general one). A pair's
standard error is kappa sqrt(sum s^2) / n_pair: the model's, from every block of the echo,
rather than the scatter of the pair's few blocks (a handful on a narrow swath).
"""

from __future__ import annotations

import logging

import numpy as np


log = logging.getLogger("clsas")

# Every EDGE_PIECES-th of the c T / 2 either side of a block must hold at least EDGE_LEVEL of the
# block's own energy a sample for the block to enter the yaw (clear_of_range_edges).
EDGE_LEVEL = 0.1
EDGE_PIECES = 8
# Blocks further than this many predicted standard deviations (kappa s) from their pair's
# median are left out of its yaw: a Gaussian block is cut with probability 6e-7.
YAW_CUT = 5.0


def clear_of_range_edges(data: np.ndarray, width: int, typical: np.ndarray) -> np.ndarray:
    """(pair, block) bool: True where every EDGE_PIECES-th of the ``width`` samples either side
    of the block holds at least EDGE_LEVEL of the block's own energy a sample, or of the pair's
    ``typical`` block's if that is lower (see the module docstring: the range-edge guard).

    data : complex (hydrophone, ping, block, sample), the records cut into range blocks;
    width : samples, c T / 2 of range (T fs, T the pulse length, fs the sampling rate), >= 1;
    typical : (pair, 1), a seafloor block's energy (summed over the block's samples, its
    hydrophones and both pings, as here), e.g. the pair's median usable block's."""
    h, pings, n_blocks, block = data.shape
    n = n_blocks * block
    power = np.einsum("hpbk,hpbk->pbk", data, np.conj(data)).real.reshape(pings, n)
    power = power[:-1] + power[1:]                                       # (pair, sample)
    total = np.concatenate([np.zeros((power.shape[0], 1)), np.cumsum(power, axis=1)], axis=1)
    lo = np.arange(n_blocks) * block                                     # block b spans [lo, lo + block)
    hi = lo + block
    observed = (lo - width >= 0) & (hi + width <= n)
    own = np.minimum(total[:, hi] - total[:, lo], typical) / block       # (pair, block)
    steps = np.round(np.linspace(0, width, EDGE_PIECES + 1)).astype(int)
    clear = observed[None, :]
    for start in (lo - width, hi):                                       # the windows before and after
        edges = np.clip(start[:, None] + steps[None, :], 0, n)          # (block, piece edge)
        length = np.maximum(np.diff(edges, axis=1), 1)
        level = np.diff(total[:, edges], axis=2) / length                # (pair, block, piece)
        clear = clear & np.all(level >= EDGE_LEVEL * own[..., None], axis=2)
    return clear


def weighted_median(x: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per row of ``x`` (pair, block): the weighted median, the midpoint of the lowest value
    below which half the row's weight ``w`` (>= 0, 0 for blocks left out) lies and the highest
    value above which half lies (the two differ where the cumulative weight meets exactly one
    half, e.g. an even count of equal weights: taking the lower one biased a trim around it
    towards the upper tail); NaN for a row without weight."""
    def lower(values):
        values = np.where(w > 0, values, np.inf)
        order = np.argsort(values, axis=1)
        xs, ws = np.take_along_axis(values, order, axis=1), np.take_along_axis(np.where(w > 0, w, 0.0), order, axis=1)
        cw = np.cumsum(ws, axis=1)
        k = np.argmax(cw >= 0.5 * cw[:, -1:], axis=1)
        return xs[np.arange(x.shape[0]), k]

    total = np.sum(np.where(w > 0, w, 0.0), axis=1)
    with np.errstate(invalid="ignore"):
        middle = 0.5 * (lower(x) - lower(-x))
    return np.where(total > 0, middle, np.nan)


def _kappa(yaw: np.ndarray, blocks: np.ndarray, s: np.ndarray) -> float | None:
    """kappa from the residuals of ``blocks`` (bool, (pair, block)) from their pair's unweighted
    mean: E (yaw_b - mean)^2 = kappa^2 (s_b^2 (1 - 2 / n) + sum s^2 / n^2), so
    E sum_b ((yaw_b - mean) / s_b)^2 = kappa^2 (n - 2 + sum s^2 sum s^-2 / n^2) a pair (n - 1 for
    equal s); None when no pair has two blocks."""
    n = blocks.sum(axis=1)
    inv = np.sum(np.where(blocks, 1 / s**2, 0.0), axis=1)
    dof = np.where(n >= 2, n - 2 + np.sum(np.where(blocks, s**2, 0.0), axis=1) * inv / np.maximum(n, 1) ** 2, 0.0)
    if not np.any(n >= 2):
        return None
    mean = np.sum(np.where(blocks, yaw, 0.0), axis=1) / np.maximum(n, 1)
    return float(np.sqrt(np.sum(np.where(blocks, ((yaw - mean[:, None]) / s) ** 2, 0.0)) / np.sum(dof)))


def yaw_mean(yaw: np.ndarray, use: np.ndarray, rho: np.ndarray, spare: np.ndarray,
             weighted: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(mean, standard error, kept) per ping pair: the unweighted mean (``weighted``: weights
    1 / s^2, the predicted inverse variances: less noise, biased, see the module docstring) of the blocks' ``yaw``
    (rad, (pair, block)) over ``use`` (bool, (pair, block), at least one a pair), blocks further
    than YAW_CUT kappa s' from the pair's median left out (s = sqrt(1 - rho^2) / rho from the
    blocks' coherence ``rho`` in (0, 1)); see the module docstring for the derivation. kappa is
    measured on the kept blocks, or, where no pair kept two (a swath of one block clear of its
    range edges), on the ``spare`` blocks (bool, (pair, block): the pairs' other usable blocks,
    edges included); the standard error is NaN (not known, with a warning) when neither has a
    pair of two blocks."""
    rho = np.clip(rho, 1e-9, 1 - 1e-9)
    s = np.sqrt(1 - rho**2) / rho
    centre = weighted_median(yaw, use.astype(float))[:, None]
    # a block's distance from the median spreads by its own s and the median's: pi / 2 times the
    # variance of the pair's mean, sum s^2 / n^2 (a block far more coherent than its pair's others
    # would otherwise be cut for the median's error)
    n = np.maximum(use.sum(axis=1, keepdims=True), 1)
    spread = np.sqrt(s**2 + np.pi / 2 * np.sum(np.where(use, s**2, 0.0), axis=1, keepdims=True) / n**2)
    z = np.abs(yaw - centre) / spread
    scale = 1.4826 * float(np.median(z[use]))
    # a scale of 0: every pair's median is its only block (or a tie of two); nothing to cut by
    kept = use & (z <= YAW_CUT * scale) if scale > 0 else use
    kappa = _kappa(yaw, kept, s)
    kappa = _kappa(yaw, spare, s) if kappa is None else kappa
    if kappa is None:
        log.warning("dpca.estimate: every ping pair's yaw rests on one range block, so its spread cannot be "
                    "measured: PingPairs.yaw_std is NaN (not known); give more range samples or shorter blocks")
        kappa = np.nan
    w = np.where(kept, 1 / s**2 if weighted else 1.0, 0.0)
    mean = np.sum(w * np.where(kept, yaw, 0.0), axis=1) / np.sum(w, axis=1)
    return mean, kappa * np.sqrt(np.sum(w**2 * s**2, axis=1)) / np.sum(w, axis=1), kept
