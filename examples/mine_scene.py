"""The classic mine-like scene (a cylinder and a truncated cone on rippled sand), simulated and
imaged by back-projection (ground plane) and omega-k (slant range): docs/images/mine_scene.png.

    python examples/mine_scene.py [OUT.png]

Prints each stage's time. See presets.mine_scene for the scene.
"""

from __future__ import annotations

import sys
import time

import numpy as np

import clsas
from clsas import plot
from clsas.scene import presets


def main(out: str = "docs/images/mine_scene.png") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    start = time.perf_counter()
    scene = presets.mine_scene()
    echo = clsas.simulate(scene, progress=False)  # spreading, absorption, bottom bounces: on (a seafloor)
    print(f"simulated {echo.data.shape} from {echo.provenance['n_scatterers']} scatterers: "
          f"{time.perf_counter() - start:.1f} s")
    compressed = clsas.range_compress(echo, window="hamming", upsample=2)
    grid = clsas.Grid.plane(x=np.arange(21.0, 33.0, 0.02), y=np.arange(-5.0, 5.0, 0.02), z=scene.seafloor.z)
    t = time.perf_counter()
    # integrate over the element's beam (lambda / D = 0.15 rad): the track samples at D / 2, so
    # the beam's edges and sidelobes alias into ghosts a full-aperture sum would show
    ground = clsas.backproject(compressed, grid, aperture=0.15, progress=False)
    print(f"back-projection {ground.data.shape}: {time.perf_counter() - t:.1f} s")
    t = time.perf_counter()
    slant = clsas.omega_k(clsas.line_record(clsas.range_compress(echo, window="hamming")), window="hamming")
    print(f"omega-k: {time.perf_counter() - t:.1f} s")
    rows, cols = np.abs(slant.axes["y"]) < 5, (slant.axes["x"] > 22.0) & (slant.axes["x"] < 34.5)
    crop = clsas.Image(data=slant.data[rows][:, cols], dims=slant.dims,
                       axes={"y": slant.axes["y"][rows], "x": slant.axes["x"][cols]})
    fig, axes = plt.subplots(1, 2, figsize=(9.5, 4.2))
    plot.plot_image(ground, floor_db=-45, ax=axes[0], title="back-projection, seafloor plane", colorbar=False)
    plot.plot_image(crop, floor_db=-45, ax=axes[1], title="omega-k, slant range", colorbar=False)
    fig.savefig(out, dpi=72, bbox_inches="tight")
    from PIL import Image  # matplotlib's own dependency: 64 colours keep the PNG near 50 kB

    Image.open(out).convert("RGB").quantize(colors=64, method=Image.Quantize.FASTOCTREE).save(out, optimize=True)
    print(f"wrote {out}: {time.perf_counter() - start:.1f} s in all")


if __name__ == "__main__":
    main(*sys.argv[1:])
