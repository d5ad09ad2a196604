"""Propagation: absorption (Francois & Garrison 1982), its envelope along an LFM pulse, and the
image sources of the sea surface and the seabed (multipath).

Absorption. Francois & Garrison 1982 (Part I, JASA 72(3) 896-907, and Part II, JASA 72(6)
1879-1890, eq. (4) of Part II) write the absorption of sea water, dB/km at f in kHz, as boric
acid + magnesium sulphate + pure water::

    alpha = A1 P1 f1 f^2 / (f1^2 + f^2) + A2 P2 f2 f^2 / (f2^2 + f^2) + A3 P3 f^2

    c  = 1412 + 3.21 T + 1.19 S + 0.0167 D                       (their sound speed, m/s)
    A1 = 8.86 / c 10^(0.78 pH - 5),  P1 = 1,  f1 = 2.8 sqrt(S / 35) 10^(4 - 1245 / (273 + T))
    A2 = 21.44 S / c (1 + 0.025 T),  P2 = 1 - 1.37e-4 D + 6.2e-9 D^2,
    f2 = 8.17 10^(8 - 1990 / (273 + T)) / (1 + 0.0018 (S - 35))
    A3 = 4.937e-4 - 2.59e-5 T + 9.11e-7 T^2 - 1.50e-8 T^3        (T <= 20 deg C)
    A3 = 3.964e-4 - 1.146e-5 T + 1.45e-7 T^2 - 6.5e-10 T^3       (T > 20 deg C)
    P3 = 1 - 3.83e-5 D + 4.9e-10 D^2

with T in deg C, S in ppt, D the depth in m (:class:`clsas.Medium`'s fields).

The loss over the band of a pulse (the derivation the kernels rely on). A path of length R
passes each frequency f with the amplitude factor exp(-a(f) R), a = alpha ln(10) / 20000 Np/m.
For an LFM of rate K and time-bandwidth product B T >> 1 the principle of stationary phase maps
each frequency of the pulse to one instant: the component at f = f0 + K u is the one emitted at
u seconds after the pulse centre. A filter H(f) that varies slowly over a band of width 1 / T
(the resolution of that map) therefore turns the echo into the echo times the envelope
H(f0 + K u) along the pulse: exactly, s_out(u) = H(f0 + K u) s(u) + O(H'' / (K^2 T^2 ... )),
the error being of the order of H's second derivative over 1 / T, far below 1e-3 for absorption
(smooth over kHz) at the ranges where it matters. clsas fits ln H over the band with a
quadratic in f - f0 (least squares on 64 points across [f0 - B/2, f0 + B/2]):

    ln H(f) = -R (a0 + a1 (f - f0) + a2 (f - f0)^2)

so the envelope is exp(-R a0) exp(beta d + gamma d^2) in the sample offset d from the echo
centre, beta = -R a1 K / fs, gamma = -R a2 (K / fs)^2: the echo kernel folds it into its chirp
recurrence (a complex quadratic exponent, :mod:`clsas.synthesis.echo.launch`), so it costs no
extra transcendental a sample. The fit's largest error (Np/m) is :attr:`BandAbsorption.error`;
times the longest path it bounds the envelope's error.

Sea-surface roughness (Rayleigh): ln R = -2 (2 pi f h sin(theta) / c)^2 is exactly quadratic in
f, so it enters the same envelope exactly (h the rms height, theta the grazing angle).

Image sources. A plane reflector maps a point p to its mirror image M(p) = p - 2 ((p - o) . n) n
(o a point of the plane, n its unit normal). A leg from A to B that bounces off planes P1 then P2
has the length of the straight segment from the image M2(M1(A)) to B, and its grazing angles
are those of that segment with the normals n1 and L1 n2 (L1 the linear part of M1). So a
path whose outgoing leg bounces is the direct path from an image transmitter (position and
element axis mapped), and one whose return leg bounces the direct path to image receivers
(their position nodes and axes mapped, so that moving receivers stay exact): each path's delay
is solved exactly (non-stop-and-go) by the same code as the direct path.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .. import validate as v
from ..model import Medium, Waveform

NP_PER_DB = np.log(10.0) / 20.0  # amplitude: x dB = x NP_PER_DB nepers
MAX_FREQUENCY = 1e7  # Hz, the formula's domain checked here (it is fitted up to 1 MHz)
FIT_POINTS = 64
SURFACE, BOTTOM = 1, 2  # reflection laws (kernels/echo_paths.cl bounce_law: 1 surface, 2 seabed)


def absorption_db_per_km(frequency_hz, medium: Medium | None = None) -> np.ndarray:
    """Absorption of sea water, dB/km, at ``frequency_hz`` (Hz, any shape, > 0) in ``medium``
    (temperature, salinity, depth, pH; default :class:`clsas.Medium`'s): Francois & Garrison
    1982 (module docstring)."""
    medium = Medium() if medium is None else medium
    if not isinstance(medium, Medium):
        raise TypeError(f"absorption_db_per_km medium: must be a Medium, got {type(medium).__name__}")
    f = v.array("absorption_db_per_km frequency_hz", frequency_hz, tuple(-1 for _ in range(np.ndim(frequency_hz))))
    if f.size and (f.min() <= 0 or f.max() > MAX_FREQUENCY):
        raise ValueError(f"absorption_db_per_km frequency_hz: must be in (0, {MAX_FREQUENCY:g}] Hz, got "
                         f"{f.min():g} .. {f.max():g}")
    f = f / 1e3  # kHz
    t, s, d, ph = medium.temperature, medium.salinity, medium.depth, medium.ph
    theta = 273.0 + t
    c = 1412.0 + 3.21 * t + 1.19 * s + 0.0167 * d
    a1 = 8.86 / c * 10.0 ** (0.78 * ph - 5.0)
    f1 = 2.8 * np.sqrt(s / 35.0) * 10.0 ** (4.0 - 1245.0 / theta)
    a2 = 21.44 * s / c * (1.0 + 0.025 * t)
    p2 = 1.0 - 1.37e-4 * d + 6.2e-9 * d * d
    f2 = 8.17 * 10.0 ** (8.0 - 1990.0 / theta) / (1.0 + 0.0018 * (s - 35.0))
    if t <= 20.0:
        a3 = 4.937e-4 - 2.59e-5 * t + 9.11e-7 * t * t - 1.50e-8 * t ** 3
    else:
        a3 = 3.964e-4 - 1.146e-5 * t + 1.45e-7 * t * t - 6.5e-10 * t ** 3
    p3 = 1.0 - 3.83e-5 * d + 4.9e-10 * d * d
    f_sq = f * f
    return a1 * f1 * f_sq / (f1 * f1 + f_sq) + a2 * p2 * f2 * f_sq / (f2 * f2 + f_sq) + a3 * p3 * f_sq


@dataclass(frozen=True)
class BandAbsorption:
    """Absorption over a pulse's band as a quadratic in f - f0 (module docstring):
    a(f) = a0 + a1 (f - f0) + a2 (f - f0)^2 Np/m; ``error`` the fit's largest error over the
    band, Np/m."""

    a0: float
    a1: float
    a2: float
    error: float

    @staticmethod
    def of(medium: Medium, waveform: Waveform) -> "BandAbsorption":
        df = np.linspace(-0.5, 0.5, FIT_POINTS) * waveform.bandwidth
        a = absorption_db_per_km(waveform.f0 + df, medium) * NP_PER_DB / 1e3
        x = df / waveform.bandwidth  # scaled for a well-conditioned fit
        c2, c1, c0 = np.polyfit(x, a, 2)
        error = float(np.max(np.abs(np.polyval([c2, c1, c0], x) - a)))
        return BandAbsorption(float(c0), float(c1 / waveform.bandwidth), float(c2 / waveform.bandwidth ** 2), error)

    def envelope(self, path_length, offset_hz) -> np.ndarray:
        """exp(-R a(f0 + offset)) for path lengths R (m) and frequency offsets (Hz), broadcast."""
        df = np.asarray(offset_hz, dtype=np.float64)
        return np.exp(-np.asarray(path_length) * (self.a0 + self.a1 * df + self.a2 * df * df))


@dataclass(frozen=True)
class Plane:
    """A reflecting plane: a point ``origin`` (3,) m, its unit ``normal`` (3,), and its law
    (:data:`SURFACE`: -exp(-2 (k h sin theta)^2) with rms height ``rms_height`` m; :data:`BOTTOM`:
    ``coefficient(grazing_rad)`` complex, the seabed's Rayleigh reflection coefficient)."""

    origin: np.ndarray
    normal: np.ndarray
    law: int
    rms_height: float = 0.0
    coefficient: object = None

    def linear(self) -> np.ndarray:
        """The reflection's linear part I - 2 n n^T (3, 3)."""
        return np.eye(3) - 2.0 * np.outer(self.normal, self.normal)


@dataclass(frozen=True)
class Affine:
    """p -> L p + t: a composition of plane reflections (identity when there is none)."""

    linear: np.ndarray = field(default_factory=lambda: np.eye(3))
    shift: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def then(self, plane: Plane) -> "Affine":
        """This map followed by the reflection in ``plane``."""
        lp = plane.linear()
        return Affine(lp @ self.linear, lp @ self.shift + 2.0 * float(plane.origin @ plane.normal) * plane.normal)

    @property
    def identity(self) -> bool:
        return bool(np.array_equal(self.linear, np.eye(3)) and not np.any(self.shift))

    def points(self, p: np.ndarray) -> np.ndarray:
        return p if self.identity else p @ self.linear.T + self.shift

    def vectors(self, d: np.ndarray) -> np.ndarray:
        return d if self.identity else d @ self.linear.T


@dataclass(frozen=True)
class Leg:
    """One leg's bounces, in the order the wave meets them going from the sonar element to the
    scatterer: ``planes`` (0, 1 or 2). ``image`` maps the element (position and axis) to its
    image; ``normals`` (k, 3) the bounces' normals in the unfolded frame (module docstring)."""

    planes: tuple = ()

    @property
    def image(self) -> Affine:
        out = Affine()
        for plane in self.planes:
            out = out.then(plane)
        return out

    @property
    def normals(self) -> np.ndarray:
        out, lin = [], np.eye(3)
        for plane in self.planes:
            out.append(lin @ plane.normal)
            lin = plane.linear() @ lin
        return np.array(out).reshape(-1, 3)

    @property
    def name(self) -> str:
        return "".join("S" if p.law == SURFACE else "B" for p in self.planes) or "D"


@dataclass(frozen=True)
class PathKind:
    """A propagation path: the outgoing leg (transmitter -> scatterer) and the return leg
    (scatterer -> receiver), each direct or bouncing. ``name`` e.g. "D-D" (direct), "S-D"
    (surface bounce on the way out), "D-BS" (back via the bottom, then the surface)."""

    out: Leg = Leg()
    back: Leg = Leg()

    @property
    def order(self) -> int:
        return len(self.out.planes) + len(self.back.planes)

    @property
    def name(self) -> str:
        return f"{self.out.name}-{self.back.name}"


DIRECT = PathKind()


def boundaries(scenario) -> tuple:
    """The scenario's reflecting planes: the sea surface (``scenario.surface``: its height z and
    rms roughness) and the seabed's mean plane (``scenario.seafloor``: ``reflection_plane()`` and
    its sediment's ``reflection_coefficient``), those present, as :class:`Plane`."""
    planes = []
    surface = getattr(scenario, "surface", None)
    if surface is not None:
        planes.append(Plane(np.array([0.0, 0.0, float(surface.z)]), np.array([0.0, 0.0, -1.0]), SURFACE,
                            rms_height=float(surface.rms_height)))
    floor = getattr(scenario, "seafloor", None)
    if floor is not None:
        origin, normal = floor.reflection_plane()
        planes.append(Plane(np.asarray(origin, float), np.asarray(normal, float), BOTTOM,
                            coefficient=floor.sediment.reflection_coefficient))
    return tuple(planes)


def path_kinds(planes, order: int) -> tuple:
    """Every path with at most ``order`` bounces (0, 1 or 2) off ``planes``, the direct one first;
    a leg never bounces twice in a row off the same plane."""
    order = v.integer("multipath order", order, low=0, high=2)
    legs = [()]
    for a in planes:
        legs.append((a,))
        for b in planes:
            if b is not a:
                legs.append((a, b))
    kinds = []
    for out in legs:
        for back in legs:
            if len(out) + len(back) <= order:
                kinds.append(PathKind(Leg(out), Leg(back)))
    return tuple(kinds)


def surface_log_coefficient(rms_height: float, sin_grazing, sound_speed: float) -> np.ndarray:
    """q (s^2) such that the rough surface reflects -exp(-q f^2) at frequency f (module docstring)."""
    return 2.0 * (2.0 * np.pi * rms_height * np.asarray(sin_grazing) / sound_speed) ** 2
