"""The seafloor's shape: a plane (flat or sloped), a height map (an array with its spacing, or a
function z(x, y)) and sand ripples, over a rectangle of the x-y plane; and its sediment.

z is up (depth is negative z), x across track, y along track (docs/design.md). The height is

    z(x, y) = z + slope_x x + slope_y y + relief(x, y) + (h / 2) sin(2 pi (x cos phi + y sin phi) / L)

with ``heights`` the relief (bicubic between the samples of an array, or your function), and
ripples of crest-to-trough height h, wavelength L and direction phi (the ripples' wave vector,
from +x towards +y: the crests run perpendicular to it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import budget
from ... import validate as v
from .sediment import LAWS, Sediment

MAX_SLOPE = 10.0  # |dz/dx|, |dz/dy| of the mean plane (84 deg)
MAX_MAP_CELLS = 10**8


@dataclass(frozen=True, eq=False)
class Seafloor:
    """A seafloor: shape, sediment, and how its speckle facets are drawn.

    Parameters
    ----------
    extent : (4,) array
        (x_min, x_max, y_min, y_max), m: the rectangle of the x-y plane where the seafloor
        scatters (facets are drawn only there, and only where the transmitter's beam reaches).
    z : float
        Height of the mean plane at x = y = 0, m (negative: below the platform at z = 0).
    sediment : Sediment or str
        A :class:`Sediment`, or a name of :data:`clsas.scene.seafloor.SEDIMENTS` (default "sand").
    law : {"apl", "lambert"}
        The backscattering law (:meth:`Sediment.backscatter_cross_section`).
    slope : (2,) array
        (dz/dx, dz/dy) of the mean plane, each within +-10.
    heights : (ny, nx) array, callable or None
        Relief added to the plane, m: samples ``heights[j, i]`` at (origin_x + i spacing,
        origin_y + j spacing), interpolated bicubically (linearly with fewer than 4 samples a
        side), which must cover ``extent``; or a function ``z(x, y)`` of arrays (m) that
        returns the relief (NumPy broadcasting; not writable to a TOML file).
    spacing : float
        The height map's sample spacing, m.
    origin : (2,) array or None
        Position of ``heights[0, 0]``, m (default: the extent's corner (x_min, y_min)).
    ripple_wavelength, ripple_height : float
        Sand ripples: wavelength L (m, > 0 when the height is) and crest-to-trough height h (m,
        0: no ripples).
    ripple_direction : float
        phi, rad: direction of the ripples' wave vector from +x towards +y.
    scatterers_per_cell : float
        Speckle: facets per resolution cell (c / 2B in range x D / 2 along track, D the
        shortest element; lambda / 4 for omnidirectional arrays); sets the facet spacing
        (default 4: the sum is then near a complex Gaussian, Rayleigh speckle).
    facet_spacing : float or None
        The facet grid's spacing, m, instead of ``scatterers_per_cell``.
    beam_nulls : int
        Facets are drawn out to this null of the transmitter's beam sinc(L sin psi / lambda)
        off its broadside, over the whole track (2: the main lobe and first sidelobes; 0:
        everywhere in ``extent``); the echo synthesis gives facets beyond it at a pulse no echo.
    seed : int
        Seeds the facets' positions within their grid cells and their phases (a facet's draws
        depend only on its cell and the seed, so the same seafloor speckles the same in any
        scenario).
    """

    extent: np.ndarray
    z: float
    sediment: Sediment | str = "sand"
    law: str = "apl"
    slope: np.ndarray = (0.0, 0.0)
    heights: object = None
    spacing: float = 1.0
    origin: np.ndarray | None = None
    ripple_wavelength: float = 0.0
    ripple_height: float = 0.0
    ripple_direction: float = 0.0
    scatterers_per_cell: float = 4.0
    facet_spacing: float | None = None
    beam_nulls: int = 2
    seed: int = 0

    def __post_init__(self):
        set_ = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731
        extent = v.array("Seafloor.extent", self.extent, (4,), bound=v.MAX_COORDINATE)
        if not (extent[0] < extent[1] and extent[2] < extent[3]):
            raise ValueError(f"Seafloor.extent: must be (x_min, x_max, y_min, y_max) with x_min < x_max and "
                             f"y_min < y_max, m, got {extent.tolist()}")
        set_("extent", extent)
        set_("z", v.scalar("Seafloor.z", self.z, low=-v.MAX_COORDINATE, high=v.MAX_COORDINATE, unit="m"))
        sediment = Sediment.named(self.sediment) if isinstance(self.sediment, str) else self.sediment
        if not isinstance(sediment, Sediment):
            raise TypeError(f"Seafloor.sediment: must be a Sediment or a sediment name, got "
                            f"{type(self.sediment).__name__}")
        set_("sediment", sediment)
        set_("law", v.choice("Seafloor.law", self.law, LAWS))
        slope = v.array("Seafloor.slope", self.slope, (2,), bound=MAX_SLOPE)
        set_("slope", slope)
        set_("spacing", v.positive("Seafloor.spacing", self.spacing, high=v.MAX_COORDINATE, unit="m"))
        origin = extent[[0, 2]] if self.origin is None else v.array("Seafloor.origin", self.origin, (2,),
                                                                      bound=v.MAX_COORDINATE)
        set_("origin", origin)
        set_("ripple_wavelength", v.scalar("Seafloor.ripple_wavelength", self.ripple_wavelength, low=0.0,
                                           high=1e3, unit="m"))
        set_("ripple_height", v.scalar("Seafloor.ripple_height", self.ripple_height, low=0.0, high=100.0, unit="m"))
        if self.ripple_height > 0 and self.ripple_wavelength == 0:
            raise ValueError(f"Seafloor.ripple_wavelength: must be > 0 m when ripple_height is > 0 "
                             f"({self.ripple_height:g} m), got 0")
        set_("ripple_direction", v.scalar("Seafloor.ripple_direction", self.ripple_direction, low=-2 * np.pi,
                                          high=2 * np.pi, unit="rad"))
        set_("scatterers_per_cell", v.scalar("Seafloor.scatterers_per_cell", self.scatterers_per_cell, low=0.01,
                                             high=1e4))
        if self.facet_spacing is not None:
            set_("facet_spacing", v.positive("Seafloor.facet_spacing", self.facet_spacing, high=1e3, unit="m"))
        set_("beam_nulls", v.integer("Seafloor.beam_nulls", self.beam_nulls, low=0, high=1000))
        set_("seed", v.integer("Seafloor.seed", self.seed, low=0, high=2**63 - 1))
        self._set_relief()

    def _set_relief(self) -> None:
        heights = self.heights
        if heights is None or callable(heights):
            object.__setattr__(self, "_map", None)
            return
        shape = np.shape(heights)
        if len(shape) == 2 and shape[0] * shape[1] > MAX_MAP_CELLS:
            raise ValueError(f"Seafloor.heights: at most {MAX_MAP_CELLS:g} samples, got {shape}")
        grid = v.array("Seafloor.heights", heights, (-1, -1), bound=v.MAX_COORDINATE)
        if min(grid.shape) < 2:
            raise ValueError(f"Seafloor.heights: must have at least 2 x 2 samples (ny, nx), got shape {grid.shape}")
        budget.check_bytes(f"Seafloor.heights {grid.shape}", 40.0 * grid.size, "a coarser height map")
        x_end = self.origin[0] + (grid.shape[1] - 1) * self.spacing
        y_end = self.origin[1] + (grid.shape[0] - 1) * self.spacing
        ext = self.extent
        if ext[0] < self.origin[0] or ext[1] > x_end or ext[2] < self.origin[1] or ext[3] > y_end:
            raise ValueError(f"Seafloor.heights: the map covers x in [{self.origin[0]:g}, {x_end:g}], y in "
                             f"[{self.origin[1]:g}, {y_end:g}] m but must cover extent {ext.tolist()} (give a larger "
                             "map, another origin or spacing, or a smaller extent)")
        from scipy.interpolate import RectBivariateSpline

        order = min(3, min(grid.shape) - 1)
        ys = self.origin[1] + self.spacing * np.arange(grid.shape[0])
        xs = self.origin[0] + self.spacing * np.arange(grid.shape[1])
        object.__setattr__(self, "heights", grid)
        object.__setattr__(self, "_map", RectBivariateSpline(ys, xs, grid, kx=order, ky=order))

    # -- geometry ----------------------------------------------------------------------------

    @property
    def has_relief(self) -> bool:
        """True when the floor is not a plane (a height map or ripples): it can shadow itself."""
        return self.heights is not None or self.ripple_height > 0

    def _ripple_phase(self, x, y):
        k = 2 * np.pi / self.ripple_wavelength
        return k * (x * np.cos(self.ripple_direction) + y * np.sin(self.ripple_direction)), k

    def height(self, x, y) -> np.ndarray:
        """z of the seafloor at (x, y) (arrays that broadcast), m."""
        x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        z = self.z + self.slope[0] * x + self.slope[1] * y
        if self._map is not None:
            z = z + self._map.ev(*np.broadcast_arrays(y, x)).reshape(np.broadcast(x, y).shape)
        elif callable(self.heights):
            z = z + np.asarray(self.heights(x, y), dtype=np.float64)
        if self.ripple_height > 0:
            phase, _ = self._ripple_phase(x, y)
            z = z + 0.5 * self.ripple_height * np.sin(phase)
        return z

    def gradient(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """(dz/dx, dz/dy) at (x, y); a height function is differentiated numerically (central
        differences over 1 mm)."""
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        gx = np.full(x.shape, self.slope[0])
        gy = np.full(x.shape, self.slope[1])
        if self._map is not None:
            gx = gx + self._map.ev(y.ravel(), x.ravel(), dy=1).reshape(x.shape)
            gy = gy + self._map.ev(y.ravel(), x.ravel(), dx=1).reshape(x.shape)
        elif callable(self.heights):
            h = 1e-3
            f = self.heights
            gx = gx + (np.asarray(f(x + h, y), dtype=np.float64) - np.asarray(f(x - h, y), dtype=np.float64)) / (2 * h)
            gy = gy + (np.asarray(f(x, y + h), dtype=np.float64) - np.asarray(f(x, y - h), dtype=np.float64)) / (2 * h)
        if self.ripple_height > 0:
            phase, k = self._ripple_phase(x, y)
            d = 0.5 * self.ripple_height * k * np.cos(phase)
            gx = gx + d * np.cos(self.ripple_direction)
            gy = gy + d * np.sin(self.ripple_direction)
        return gx, gy

    def normal(self, x, y) -> np.ndarray:
        """Unit upward normal at (x, y): shape ``broadcast(x, y).shape + (3,)``."""
        gx, gy = self.gradient(x, y)
        n = np.stack([-gx, -gy, np.ones_like(gx)], axis=-1)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    def reflection_plane(self) -> tuple[np.ndarray, np.ndarray]:
        """The mean plane a bottom bounce reflects in: a point (0, 0, z) and its unit upward
        normal, both (3,) (relief and ripples left out)."""
        n = np.array([-self.slope[0], -self.slope[1], 1.0])
        return np.array([0.0, 0.0, self.z]), n / np.linalg.norm(n)

    def height_range(self, samples: int = 257) -> tuple[float, float]:
        """Bounds (lowest, highest) of z over ``extent``, m: a grid of ``samples`` per side, widened
        by the ripples' half height (so that sampling cannot miss their crests and troughs)."""
        x = np.linspace(self.extent[0], self.extent[1], samples)
        y = np.linspace(self.extent[2], self.extent[3], samples)
        z = self.height(x[None, :], y[:, None])
        margin = 0.5 * self.ripple_height
        return float(z.min()) - margin, float(z.max()) + margin

    def mesh(self, spacing: float, bounds: np.ndarray | None = None):
        """The seafloor as a triangle mesh (trimesh, world frame) over ``bounds`` (x_min, x_max,
        y_min, y_max; default and at most ``extent``), its vertices on a grid of at most
        ``spacing`` m (two triangles for a plane). Ray casting against it shadows the relief."""
        import trimesh

        ext = self.extent if bounds is None else np.asarray(bounds, dtype=np.float64)
        x0, x1 = max(ext[0], self.extent[0]), min(ext[1], self.extent[1])
        y0, y1 = max(ext[2], self.extent[2]), min(ext[3], self.extent[3])
        if not (x0 < x1 and y0 < y1):
            raise ValueError(f"Seafloor.mesh: bounds {np.asarray(ext).tolist()} miss the extent {self.extent.tolist()}")
        if self.has_relief:
            v.positive("Seafloor.mesh spacing", spacing, high=v.MAX_COORDINATE, unit="m")
            nx, ny = int(np.ceil((x1 - x0) / spacing)) + 1, int(np.ceil((y1 - y0) / spacing)) + 1
        else:
            nx = ny = 2
        budget.check_bytes(f"the seafloor's relief mesh ({nx} x {ny} vertices)", 80.0 * nx * ny,
                           "a coarser relief mesh (a larger facet spacing)")
        x, y = np.meshgrid(np.linspace(x0, x1, nx), np.linspace(y0, y1, ny))
        vertices = np.column_stack([x.ravel(), y.ravel(), self.height(x, y).ravel()])
        corner = (np.arange(ny - 1)[:, None] * nx + np.arange(nx - 1)[None, :]).ravel()
        faces = np.concatenate([np.column_stack([corner, corner + 1, corner + nx + 1]),
                                np.column_stack([corner, corner + nx + 1, corner + nx])])
        return trimesh.Trimesh(vertices, faces, process=False)

    def max_slope(self, samples: int = 513) -> float:
        """An upper bound of |grad z| over ``extent``: the plane's and the height map's largest
        gradient sampled on a grid of ``samples`` per side, plus the ripples' slope amplitude
        pi h / L (a ray leaving the floor at an elevation tan e above this cannot meet it again)."""
        x = np.linspace(self.extent[0], self.extent[1], samples)
        y = np.linspace(self.extent[2], self.extent[3], samples)
        flat = Seafloor(self.extent, self.z, self.sediment, self.law, self.slope, self.heights, self.spacing,
                        self.origin) if self.ripple_height > 0 else self
        gx, gy = flat.gradient(x[None, :], y[:, None])
        return float(np.hypot(gx, gy).max()) + np.pi * self.ripple_height / max(self.ripple_wavelength, 1e-300)
