"""ffbp's first stage with an integration angle: the leaves' samples that no pulse sees within the
aperture (:func:`clsas.image.ffbp.polar.within_aperture`) are zero and are not back-projected.

Scene: test_ffbp's (Huang & Yang 2022's sonar over a 4 x 4 m grid 42-46 m across track, a speckle
of random scatterers), imaged with a narrow integration angle (APERTURE: |sin| <= 0.025, so each
pulse sees a strip of about 2.2 m of the grid's 4 m along track); on the straight track, with sway
and yaw, and on the straight track mirrored (y -> -y: heading along -y, the scene mirrored with it).
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest
from test_ffbp import GRID, echo_of

from clsas.image.ffbp import ffbp, reuse
from clsas.image.ffbp.leaves import FirstStage
from clsas.image.ffbp.polar import Scene, within_aperture
from clsas.image.ffbp.tree import plan

leaves_module = importlib.import_module("clsas.image.ffbp.leaves")
APERTURE = 0.05


def _echo(track: str):
    if track != "reversed":
        return echo_of(track, "speckle")
    echo, flip = echo_of("straight", "speckle"), np.array([1.0, -1.0, 1.0])
    return echo.replace(tx_pos=echo.tx_pos * flip, rx_pos=echo.rx_pos * flip)


def _leaves(track: str, first: int):
    echo = _echo(track)
    chosen = list(range(echo.n_rx))
    tree = plan(echo, chosen, Scene.of(GRID.positions), 2, 0.1, 8, first, APERTURE)
    return echo, chosen, tree


@pytest.mark.parametrize("track", ["straight", "motion", "reversed"])
def test_samples_cut_off_are_zero_in_the_reference_leaves(track):
    """The NumPy reference (float64, the mask |sin| <= sin(aperture / 2) of every pulse) gives
    exactly zero at every sample of a leaf's spans that within_aperture cuts off, on a straight
    track and with sway and yaw (|u - y| > 0), and the cut is not empty (measured: 23.8 % of the
    straight track's leaf samples and 13.8 % of the other's)."""
    echo, chosen, tree = _leaves(track, 2)
    grids = tree.grids[0]
    stage = FirstStage(echo, tree.pulses[0], "numpy", chosen, "linear", 8, APERTURE, False)
    alive = [k for k, g in enumerate(grids) if g is not None and tree.pulses[0][k][1] - tree.pulses[0][k][0] == 2]
    pulses = np.array([tree.pulses[0][k][0] for k in alive])[:, None] + np.arange(2)
    seen = within_aperture([grids[k] for k in alive], echo.tx_pos[pulses], np.sin(APERTURE / 2))
    cut = total = 0
    for k, narrow in zip(alive, seen):
        image = stage.image(k, grids[k], grids)
        off = grids[k].inside() & ~narrow.inside()
        assert np.all(image[off] == 0), (k, int(np.count_nonzero(image[off])))
        cut, total = cut + int(off.sum()), total + grids[k].computed
    print(track, f"cut {cut / total:.3f} of {total} leaf samples")
    assert cut > 0.1 * total


@pytest.mark.parametrize("track", ["straight", "motion", "reversed"])
def test_the_cut_changes_no_image_and_skips_work_items(opencl_device, monkeypatch, track):
    """ffbp with the cut and without it (within_aperture patched to cut nothing): the same image bit
    for bit (the cut samples are zero either way, and the tiles are chosen on every sample as
    before, so bp_tile's references are the same); with the cut fewer work-items are
    back-projected (measured 1804 of 2112 items on the straight track, 4128 of 5232 with motion)."""
    echo = _echo(track)
    monkeypatch.setattr(reuse, "KEEP_PLANS", False)  # each call lays its first stage out anew
    counts = []
    real_tiles = leaves_module.polar_tiles

    def counted(grids, bv, br, seen=None):
        items, centres, n_tiles, n_items = real_tiles(grids, bv, br, seen)
        counts.append((items.size, n_items))
        return items, centres, n_tiles, n_items

    monkeypatch.setattr(leaves_module, "polar_tiles", counted)
    cut = ffbp(echo, GRID, aperture=APERTURE, backend="opencl", progress=False)
    monkeypatch.setattr(leaves_module, "within_aperture", lambda grids, tx, h: grids)
    whole = ffbp(echo, GRID, aperture=APERTURE, backend="opencl", progress=False)
    assert cut.data.tobytes() == whole.data.tobytes()
    half = len(counts) // 2
    with_cut, without = counts[:half], counts[half:]
    assert [n for n, _ in with_cut] == [n for n, _ in without]  # the same tiles' items laid out
    assert all(n == m for n, m in without)
    print(track, "items back-projected", sum(m for _, m in with_cut), "of", sum(n for n, _ in with_cut))
    assert sum(m for _, m in with_cut) < 0.95 * sum(n for n, _ in with_cut)


def test_a_track_heading_along_minus_y_is_limited_as_one_along_y():
    """The integration angle's sine is taken off the y axis either way along it (bp_tile keeps
    |sin| <= sin(aperture / 2)), so the polar grids of a track heading along -y are limited to the
    angles its pulses see as those of the same track along +y: the mirrored scene's tree holds
    about the samples of the straight one's (measured 31021 leaf samples against 31091, one level
    each; on 56f79b2 the limit took |u - y| = 2 for it, so its grids covered every angle: 135386
    leaf samples and three levels here, and 1.36x direct back-projection's speed instead of 3.53x
    on bench_ffbp's aperture case mirrored)."""
    straight, mirrored = (_leaves(track, None)[2] for track in ("straight", "reversed"))
    assert straight.first == mirrored.first and straight.top == mirrored.top
    assert all(abs(a - b) <= 0.02 * a for a, b in zip(straight.samples(), mirrored.samples()))
