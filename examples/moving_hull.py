"""A moving submarine focused whole: Kiang & Kiang 2022 Table II case 1 (the Albacore scaled to
~10 m, moving at (0, -4, 0) m/s), its velocity estimated from receivers A, B and sonobuoy C, and
the hull focused at A by back-projection in its moving frame (``clsas.focus_moving``, every
scatterer with its own delay history) beside the paper's chain (``method="paper"``: the
reference point's history for the whole image) and the scan image of the mesh:
docs/images/moving_hull.png.

    python examples/moving_hull.py [OUT.png] [N_PULSES]

Prints each stage's time and the estimate.
"""

from __future__ import annotations

import sys
import time

import numpy as np

import clsas
from clsas import plot
from clsas.scene import presets
from clsas.synthesis.occlusion import scan_image

CENTRE = (1989.0, 0.0, -350.0)


def main(out: str = "docs/images/moving_hull.png", n_pulses: int = 2048) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start = time.perf_counter()
    scene = presets.kiang2022_case(1, n_pulses=n_pulses, sections=48, stations=60)
    echo = clsas.simulate(scene, progress=False)
    print(f"simulated {echo.data.shape}: {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    est = clsas.estimate_motion(echo, position=CENTRE)
    print(f"estimated v = {np.round(est.velocity, 3)} m/s (sigma {np.round(est.sigma, 3)}, confidence "
          f"{est.confidence:.2f}): {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    bp = clsas.focus_moving(echo, est, half_size=(1.5, 7.0), spacing=0.03)["A"]
    print(f"focused (back-projection in the target's frame, A, B, C): {time.perf_counter() - start:.1f} s")
    start = time.perf_counter()
    paper = clsas.focus_moving(echo, est, method="paper", tau_span=2 * 3.0 / 1500.0)["A"]
    print(f"focused (the paper's chain, A, B, C): {time.perf_counter() - start:.1f} s")
    r, y = bp.axes["r"], bp.axes["y"]
    scan = scan_image(scene, r, y, eta=est.layout.eta_ref)
    fig, axes = plt.subplots(1, 3, figsize=(10, 5))
    for ax, image, title in ((axes[0], bp, "focus_moving, A (bp)"),
                             (axes[1], paper, 'method="paper", A'),
                             (axes[2], scan, "scan image (mesh, A)")):
        plot.plot_image(image, floor_db=-35.0, ax=ax, title=title, colorbar=False)
        ax.set_xlim(r[0], r[-1])
        ax.set_ylim(y[0], y[-1])
        ax.set_aspect("auto")
    fig.suptitle(f"Kiang & Kiang 2022 case 1, {n_pulses} pulses: v estimated {np.round(est.velocity, 3)} m/s")
    fig.savefig(out, dpi=60, bbox_inches="tight")
    print(f"wrote {out}")


if __name__ == "__main__":
    main(*(sys.argv[1:2] or []), *([int(sys.argv[2])] if len(sys.argv) > 2 else []))
