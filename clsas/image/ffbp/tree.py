"""The merge tree of fast factorised back-projection: sub-apertures, their frames and polar grids.

Level 0 holds the leaves, blocks of ``first`` consecutive pulses (the last one shorter; by
default the fewest, doubling from one, whose polar grid at the track's middle spans LEAF_SAMPLES
angles besides its padding and that make at most MAX_LEAVES leaves, or half or twice as many
pulses, whichever tree costs least by the estimate below);
a node of level l + 1 is ``factor`` consecutive nodes of level l. A node's frame:

- centre C: the mean of its phase centres, the midpoints of the transmitter at emission and
  each selected receiver at each of its position nodes over the recording (a receiver that moves
  while it records has its phase centre move with the echo's delay: a one-pulse node has a
  length too);
- axis u: the unit chord of the transmitter's track from the node's first to its last pulse
  (a one-pulse node: the chord over its neighbours);
- half-length L: max |a| + max |b| + max |T - R|^2 / (4 r_near) over its phase centres, a
  the offset along u and b the distance off it; the last term bounds the two-leg bistatic
  delay's departure from twice the range to the midpoint, (|X - T| + |X - R|) - 2 |X - M|
  <= |T - R|^2 / (4 |X - M|) (r_near the nearest scene range).

Its polar grid covers the scene within the recorded range window widened by L + max |T - R| / 2
and, with an ``aperture``, the angles |v| <= sin(aperture / 2) + min(|u - y|, |u + y|) + (E + slack)
/ (r_C - E), E = max |T - C| over the node's transmitters T and r_C = the distance from the node's centre C
to the scene's skeleton less its margin, below every pixel's |X - C| (the pixels that some pulse of the node
sees within the aperture: bp_tile's mask takes the |sine| off the y axis at the transmitter, so a
track heading along -y is limited as one along +y; :func:`clsas.image.ffbp.polar.aperture_sines`),
and for an axis turned from y within the window :func:`clsas.image.ffbp.polar.aperture_windows`
derives from the scene's extremes across y (a yawed track's |u - y| leaves the first bound near 1);
:func:`clsas.image.ffbp.polar.extents` bounds it and :meth:`~clsas.image.ffbp.polar.Extent.sample`
samples it.

Where to stop: merging level l into level l + 1 costs about factor x (the samples of level l + 1)
interpolations and saves, at the final stage, the pixels' reads of level l's nodes less those of
level l + 1's (a node is read at the pixels its grid covers, about its extent's ``reach`` x the
pixels: with an ``aperture`` a node sees only a sector of a long scene); the tree merges while
that pays. The oversampling rho depends on the number of stages
(:func:`clsas.image.ffbp.polar.oversampling`), which depends on where the tree stops: a first
guess settled by the rule on the grids' (r, v) boxes (unsampled, so cheap) and two rounds on the
sampled grids settle both, and the oversampling is that of the tree's final number of stages in
any case (the rule of the error model holds even where the rounds did not settle).

The leaf length by cost: a tree of n-pulse leaves costs about its leaves' samples x (LEAF_SAMPLE_COST
+ LEAF_PULSE_COST x n x receivers) (a leaf sample's fields and demodulation, and bp_tile's work a
pulse; both in merge interpolations, as bench_ffbp --stages measures them), factor x the samples
of each level it merges and the pixels' reads of its top nodes, each level's samples and reach
estimated as its node count x those of the level's node that holds the middle pulse (its spine:
nodes the rule above probes anyway), its top by the rule on the spine. The estimate only chooses
among trees: each tree, whatever its leaves, gets its oversampling from its own stages.
"""

from __future__ import annotations

import dataclasses
import logging

import numpy as np

from ...model import EchoData
from .polar import Scene, aperture_windows, extents, oversampling, sample_grids

_log = logging.getLogger("clsas")

LEAF_SAMPLES = 16  # the default first stage: the fewest pulses whose leaf grid is at least this wide in angle
MAX_LEAVES = 64  # ... and no more leaves than this (a leaf's launches and host work cost alike however short it is)
# a leaf sample's back-projection of one pulse of one receiver (a bp_tile lane-pulse), in merge interpolations
# (bench_ffbp --stages reports both, op_ns: leaf_lane_pulse, merge_interpolation), as measured with PoCL's
# AVX-512 kernels (session 13; AVX2 kernels or another device move the ratio: the choice among valid trees only)
LEAF_PULSE_COST = 0.11
LEAF_SAMPLE_COST = 1.5  # ... and a leaf sample's own in a cold call (its layout's fields, demodulation: leaf_sample)


@dataclasses.dataclass
class Tree:
    """pulses[l][n] = (p0, p1) of node n of level l; children[l][n] its children (level l - 1);
    grids[l][n] its PolarGrid (None: it sees no pixel); ``top`` the last level merged (its nodes
    go to the pixels), ``rho`` the oversampling, ``first`` pulses a leaf (``ruled``: the rule chose
    it, plan's first=None; False: the caller gave it)."""

    pulses: list
    children: list
    grids: list
    top: int
    rho: float
    first: int
    ruled: bool = True

    def samples(self) -> list[int]:
        """Polar samples computed (inside their rows' spans) of each level up to the top."""
        return [int(sum(g.computed for g in level if g is not None)) for level in self.grids[:self.top + 1]]


def _spine(n_pulses: int, first: int, factor: int) -> tuple[list, list]:
    """The node (p0, p1) holding the middle pulse at each level of the tree of ``first``-pulse leaves
    (:func:`_levels`, up to its root), and the number of nodes of each level."""
    nodes, counts, span = [], [], first
    while True:
        count = -(-n_pulses // span)
        start = (n_pulses // 2) // span * span if count > 1 else 0
        nodes.append((start, min(start + span, n_pulses)))
        counts.append(count)
        if count == 1:
            return nodes, counts
        span *= factor


def _levels(n_pulses: int, first: int, factor: int):
    pulses = [[(p, min(p + first, n_pulses)) for p in range(0, n_pulses, first)]]
    children = [[[] for _ in pulses[0]]]
    while len(pulses[-1]) > 1:
        below = pulses[-1]
        groups = [list(range(i, min(i + factor, len(below)))) for i in range(0, len(below), factor)]
        pulses.append([(below[g[0]][0], below[g[-1]][1]) for g in groups])
        children.append(groups)
    return pulses, children


class _Frames:
    """Phase centres and bistatic baselines of the echo's pulses, and node frames from them."""

    def __init__(self, echo: EchoData, chosen: list, scene: Scene):
        rx = np.moveaxis(echo.rx_pos[chosen], 2, 1)  # (n_sel, nodes, N, 3): each receiver over its recording
        rx = rx.reshape(-1, *rx.shape[2:])  # (n_sel x nodes, N, 3), receiver by receiver
        self.tx = echo.tx_pos
        self.mids = 0.5 * (self.tx[None] + rx)
        self.baseline = np.linalg.norm(rx - self.tx[None], axis=-1).max(axis=0)  # (N,)
        step = max(1, echo.n_pulses // 64)  # the array's two ends every ~1/64 of the track
        ends = sorted({0, rx.shape[0] - 1})  # the first receiver's first node, the last one's last (or the same)
        track = np.concatenate([self.mids[ends, ::step].reshape(-1, 3), self.mids[ends, -1]])
        self.r_near = float(scene.nearest(track).min()) - scene.margin

    def frames(self, nodes: list, reach: bool = False) -> tuple:
        """(centres (n, 3), axes (n, 3), half-lengths (n,), largest baselines (n,), reach) of the nodes
        (p0, p1) (pulses p0..p1-1), vectorised over the nodes of each length; ``reach``: also max |T - C|
        (n,) m over the transmitter's positions T at the emissions of each node's pulses, C its centre
        (how far from C bp_tile's aperture mask takes its angles), else None. A length's nodes are laid
        out pulse-major, (pulses, nodes, 3): the centre's sum runs over the pulses one after the other
        as NumPy's mean over a node-major array's pulse axis does, a whole row of nodes at a time."""
        n = self.tx.shape[0]
        centres, axes = np.empty((len(nodes), 3)), np.empty((len(nodes), 3))
        halves, bases = np.empty(len(nodes)), np.empty(len(nodes))
        reaches = np.empty(len(nodes)) if reach else None
        by_length = {}
        for i, (p0, p1) in enumerate(nodes):
            by_length.setdefault(p1 - p0, []).append(i)
        for length, which in by_length.items():
            p0 = np.array([nodes[i][0] for i in which])
            lo, hi = (p0, p0 + length - 1) if length > 1 else (np.maximum(p0 - 1, 0), np.minimum(p0 + 1, n - 1))
            chord = self.tx[hi] - self.tx[lo]
            norm = np.linalg.norm(chord, axis=1)[:, None]
            axis = np.where(norm > 0, chord / np.where(norm > 0, norm, 1.0), [0.0, 1.0, 0.0])
            pulses = np.arange(length)[:, None] + p0  # (length, m)
            mids = np.take(self.mids, pulses, axis=1).reshape(-1, len(which), 3)  # (receivers x length, m, 3)
            centre = np.add.reduce(mids, axis=0) / mids.shape[0]
            d = mids - centre
            along = np.einsum("kmi,mi->km", d, axis)
            off = d - along[..., None] * axis
            base = np.take(self.baseline, pulses).max(axis=0)
            centres[which], axes[which], bases[which] = centre, axis, base
            halves[which] = (np.abs(along).max(axis=0) + np.sqrt(np.einsum("kmi,kmi->km", off, off)).max(axis=0)
                             + base ** 2 / (4 * self.r_near))
            if reach:
                d = np.take(self.tx, pulses, axis=0) - centre
                reaches[which] = np.sqrt(np.einsum("kmi,kmi->km", d, d).max(axis=0))
        return centres, axes, halves, bases, reaches


def plan(echo: EchoData, chosen: list, scene: Scene, factor: int, tolerance: float, taps: int,
         first: int | None, aperture: float | None, *, device: bool = False, first_guess: int | None = None) -> Tree:
    """The merge tree for ``echo``'s pulses and the scene (see the module docstring); ``device``:
    the extents' reductions over the skeleton on the OpenCL device (the same tree, bit for bit:
    :mod:`.polar.offsets`); ``first_guess``: a likely leaf length for ``first=None`` (checked by the
    rule, not trusted: the tree is the same whatever it is; a right one spares a round of extents)."""
    frames = _Frames(echo, chosen, scene)
    if frames.r_near <= 0:
        raise ValueError("grid: a pixel lies on the sonar's track (zero range); ffbp's polar grids need every pixel "
                         "at a positive range from the phase centres")
    c, f0, bw = echo.medium.sound_speed, echo.waveform.f0, echo.waveform.bandwidth
    t_lo = float(echo.t0[chosen].min())
    t_hi = float(echo.t0[chosen].max()) + echo.n_samples / echo.fs
    sine = None if aperture is None else np.sin(aperture / 2)
    n_pixels = scene.pixels
    window = np.array([c * t_lo / 2, c * t_hi / 2])
    extents_of, grids_at = {}, {}

    def find_extents(nodes):
        """The extents (all but the sampling) of the nodes (p0, p1) not yet known, at once."""
        nodes = [n for n in dict.fromkeys(nodes) if n not in extents_of]
        if not nodes:
            return
        centres, axes, halves, bases, reaches = frames.frames(nodes, reach=sine is not None)
        widen = halves + bases / 2
        limits = None if sine is None else aperture_windows(scene, centres, axes, sine, reaches,
                                                            scene.nearest(centres) - scene.margin,
                                                            taps if device else None)
        found = extents(centres, axes, halves, scene, window + np.stack([-widen, widen], axis=1), bw, f0, c, limits,
                        taps if device else None)
        extents_of.update(zip(nodes, found))

    def sample(pairs: list) -> None:
        """The polar grids of the (node (p0, p1), oversampling) pairs not yet sampled, at once (None: a
        node that sees nothing)."""
        new = [pair for pair in dict.fromkeys(pairs) if pair not in grids_at]
        if not new:
            return
        find_extents([node for node, _ in new])
        seen = [pair for pair in new if extents_of[pair[0]] is not None]
        grids_at.update({pair: None for pair in new})
        grids_at.update(zip(seen, sample_grids([extents_of[node] for node, _ in seen], [rho for _, rho in seen],
                                               taps)))

    def grids_for(nodes, rho) -> list:
        """The polar grids of the nodes (p0, p1) at oversampling rho (None: a node that sees nothing),
        those not yet sampled at once."""
        sample([(node, rho) for node in nodes])
        return [grids_at[(node, rho)] for node in nodes]

    def reach(nodes) -> float:
        """Pixels read at the final stage a pixel if these nodes were the top ones (kernels/ffbp.cl skips
        a node whose grid a pixel is not in)."""
        return sum(extents_of[node].reach for node in nodes if extents_of[node] is not None)

    def spine(n: int) -> tuple:
        """The tree of ``n``-pulse leaves estimated from its spine (:func:`_spine`: each level's samples
        and reach taken as its node count x those of its node holding the middle pulse): its spine's
        nodes, their levels' node counts and reach, and the top the rule (:func:`stop`'s) settles on
        the spine's boxes (as the plan's first guess is) with its oversampling and the levels' box
        samples up to it; None when the middle leaf sees nothing or the tree's stages cannot meet the
        tolerance."""
        nodes, counts = _spine(echo.n_pulses, n, factor)
        found = [extents_of[node] for node in nodes]
        if found[0] is None:
            return None
        covered = [count * (0.0 if e is None else e.reach) for count, e in zip(counts, found)]
        def sized(top):  # the oversampling of a tree topped at level top and the levels' box samples at it
            rho = oversampling(taps, tolerance, top + 1)
            return rho, [count * (0 if e is None else e.size(rho, taps)) for count, e in zip(counts, found)]

        top = min(1, len(nodes) - 1)
        try:  # ValueError: a tree this deep cannot meet the tolerance: not a candidate
            for _ in range(3):
                rho, sizes = sized(top)
                guess = 0
                while guess + 1 < len(nodes) and factor * sizes[guess + 1] <= n_pixels * (covered[guess]
                                                                                           - covered[guess + 1]):
                    guess += 1
                if guess == top:
                    break
                top = guess
            else:  # not settled: the last guess's own oversampling and sizes
                rho, sizes = sized(top)
        except ValueError:
            return None
        return nodes[:top + 1], counts[:top + 1], covered[top], rho, sizes[:top + 1]

    def estimated_costs(near: list, guessed: list) -> dict:
        """The estimated cost, in merge interpolations, of the trees of each of ``near``'s leaf lengths
        (:func:`spine`; inf for None): its leaves' (LEAF_SAMPLE_COST a sample besides LEAF_PULSE_COST a
        sample, pulse and receiver), its merges' (factor a sample of each merged level) and its final
        stage's (a read a pixel and top node whose grid covers it), in the samples computed (the rows'
        spans): the middle leaf's sampled grid's, and the merged levels' boxes x the share of its box
        that leaf computes (its upper levels, whose grids are the largest, not sampled). The grids of
        the levels of the ``guessed`` tree (pulses of each level's nodes, or none) that its first
        sampled round reads if its spine's top is right are sampled with the leaves' (one call; the
        same grids whatever the choice)."""
        spines = {n: spine(n) for n in near}
        pairs = [(s[0][0], s[3]) for s in spines.values() if s is not None]
        if guessed and spines.get(guessed[0][0][1] - guessed[0][0][0]) is not None:
            nodes, _, _, rho, _ = spines[guessed[0][0][1] - guessed[0][0][0]]
            pairs += [(node, rho) for level in guessed[:len(nodes) + 1] for node in level]
        sample(pairs)
        costs = {}
        for n, s in spines.items():
            if s is None:
                costs[n] = np.inf
                continue
            nodes, counts, covered, rho, sizes = s
            leaf = grids_for(nodes[:1], rho)[0]
            share = leaf.computed / max(leaf.size, 1)
            costs[n] = ((LEAF_SAMPLE_COST + LEAF_PULSE_COST * len(chosen) * n) * counts[0] * leaf.computed
                        + factor * share * sum(sizes[1:]) + n_pixels * covered)
        return costs

    ruled = first is None
    if first is None:
        # the fewest pulses whose middle leaf is wide enough (doubling from one, whatever the factor: a
        # factor of 4 would jump past the best; lengths that make more than MAX_LEAVES leaves are
        # passed over), then that length or a neighbour (half, double) by their estimated costs.
        # The lengths' middle nodes and the root (every tree's spine, for a factor that is a power of
        # two) are probed at once, with a guess (the last tree's length on this grid) together with the
        # guessed tree's nodes (the same answer either way: each node's extent is its own, however
        # many are found at once; a right guess spares a round of extents)
        rho0 = oversampling(taps, tolerance, 1)
        lengths = [1 << k for k in range(max(echo.n_pulses - 1, 1).bit_length())
                   if -(-echo.n_pulses // (1 << k)) <= MAX_LEAVES]
        middles = [(echo.n_pulses // 2, min(echo.n_pulses // 2 + n, echo.n_pulses)) for n in lengths]
        guessed = _levels(echo.n_pulses, first_guess, factor)[0] if first_guess in lengths else []
        find_extents(middles + [(0, echo.n_pulses)] + [node for level in guessed for node in level])
        passing = [n for n, m in zip(lengths, middles)
                   if extents_of[m] is not None and extents_of[m].rows(rho0, taps) - 2 * taps >= LEAF_SAMPLES]
        first = passing[0] if passing else echo.n_pulses
        if first in lengths:
            near = [n for n in (first // 2, first, 2 * first) if n in lengths]
            find_extents([node for n in near for node in _spine(echo.n_pulses, n, factor)[0]])
            costs = estimated_costs(near, guessed)
            first = min(near, key=lambda n: (costs[n], n != first))  # the rule's length on a tie
            _log.debug("ffbp: leaf lengths' estimated costs %s (merge interpolations): %d pulses a leaf", costs, first)
    pulses, children = _levels(echo.n_pulses, first, factor)
    find_extents([node for level in pulses for node in level])

    def stop(rho: float, samples) -> int:
        """The top level where merging stops paying at oversampling rho (the module docstring's
        rule), a level's merge costing factor x ``samples(nodes, rho)`` interpolations."""
        new_top = 0
        while new_top + 1 < len(pulses):
            level = new_top + 1
            if factor * samples(pulses[level], rho) > n_pixels * (reach(pulses[new_top]) - reach(pulses[level])):
                break
            new_top = level
        return new_top

    def boxes(nodes, rho) -> int:
        """The samples of the nodes' polar boxes at rho (the grids unsampled: at least those computed)."""
        return sum(extents_of[node].size(rho, taps) for node in nodes if extents_of[node] is not None)

    def computed(nodes, rho) -> int:
        return sum(g.computed for g in grids_for(nodes, rho) if g is not None)

    # a first guess settled on the boxes (no grid sampled; from one merge level, where most trees
    # stop), then the rule on the sampled grids: two rounds settle both (a lower oversampling
    # merges at least as far), and a right guess saves sampling the grids at a wrong one
    top = min(1, len(pulses) - 1)
    for _ in range(3):
        guess = stop(oversampling(taps, tolerance, top + 1), boxes)
        if guess == top:
            break
        top = guess
    for _ in range(2):
        rho = oversampling(taps, tolerance, top + 1)
        # the levels the rule reads if the guess holds (up to the one above it), sampled at once
        grids_for([node for level in pulses[:top + 2] for node in level], rho)
        if all(g is None for g in grids_for(pulses[0], rho)):
            angle = "" if aperture is None else f" and within the integration angle ffbp aperture={aperture!r} rad"
            raise ValueError(f"grid: no pixel lies within the recorded range window{angle} of any sub-aperture: the "
                             "sonar never sees this grid")
        new_top = stop(rho, computed)
        if new_top == top:
            break
        top = new_top
    rho = oversampling(taps, tolerance, top + 1)  # the stages of the tree as it stands, settled or not
    grids = [grids_for(pulses[level], rho) if level <= top else [] for level in range(len(pulses))]
    return Tree(pulses, children, grids, top, rho, first, ruled)
