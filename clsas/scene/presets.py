"""The sonars of the five source papers, by name, as Scenarios (targets come from the echo stage).

Each preset takes the values of the paper's parameter table; what the paper does not give is
chosen here and marked "assumed" in the docstring (a reasoned value, never silently).

===============  ======================================================================
name             source
===============  ======================================================================
``kiang2022``    Kiang & Kiang 2022, Table I (the default sonar): towed transceiver A,
                 towed receiver B, sonobuoy C
``huang2022``    Huang & Yang 2022, Table 1: 32-receiver MSAS
``wu2018``       Wu, Tang & Zhong 2018, Table 1: 32-hydrophone array
``zhang2019``    Zhang, Tan & Ying 2019, Table 1: multireceiver SAS
``heremans2009`` Heremans, Dupont & Acheroy 2009, section 5.2: 15-hydrophone DPCA array
===============  ======================================================================
"""

from __future__ import annotations

import numpy as np

from .scenario import (
    Array,
    Medium,
    Platform,
    PulseSchedule,
    Scenario,
    Sonobuoy,
    Waveform,
)
from .seafloor import Seafloor
from .targets import PointTargets


def _line_array_sonar(array: Array, waveform: Waveform, speed: float, prf: float, n_pulses: int) -> Scenario:
    """A straight-track sonar at depth 0 in water of 1500 m/s (the 2-D papers' set-up)."""
    return Scenario(medium=Medium(1500.0), waveform=waveform, platform=Platform(speed=speed), array=array,
                    schedule=PulseSchedule(prf=prf, n_pulses=n_pulses))


def kiang2022(n_pulses: int | None = None) -> Scenario:
    """Kiang & Kiang 2022, Table I, and section II.

    c = 1.5 km/s; V_p = 3 m/s; L1 = L2 = 250 m; theta_b = 10 deg; f0 = 150 kHz;
    K_r = 4 MHz/s; T_r = 5 ms; B_r = 20 kHz; F_r = 20 kHz; PRF F_a = 80 Hz; T_a = 80 s
    (6400 pulses, centred on eta = 0).

    Transceiver A at (0, V eta, -L1 sin theta_b) (the platform reference point, depth 43.4 m),
    towed receiver B at (0, V eta - L2, -L1 sin theta_b), sonobuoy C at (-500, 0, -150) m.
    The paper gives no element sizes: all elements are omnidirectional (assumed).
    ``n_pulses`` replaces the 80 s exposure (for small runs), keeping the PRF.
    """
    depth = -250.0 * np.sin(np.deg2rad(10.0))
    array = Array(rx_offsets=[[0.0, 0.0, 0.0], [0.0, -250.0, 0.0]], names=("A", "B"))
    schedule = PulseSchedule(prf=80.0, exposure=80.0) if n_pulses is None else PulseSchedule(prf=80.0, n_pulses=n_pulses)
    return Scenario(
        medium=Medium(1500.0),
        waveform=Waveform(f0=150e3, bandwidth=20e3, duration=5e-3, fs=20e3),
        platform=Platform(speed=3.0, start=(0.0, 0.0, depth)),
        array=array,
        schedule=schedule,
        sonobuoys=(Sonobuoy((-500.0, 0.0, -150.0), name="C"),),
    )


def huang2022(n_pulses: int = 256) -> Scenario:
    """Huang & Yang 2022, Table 1: V = 2 m/s, PRI 0.32 s, B = 20 kHz, f0 = 150 kHz,
    32 receivers over 1.28 m (receiver width 0.04 m), transmitter width 0.08 m.

    Receivers ahead of the transmitter at d_i = 0.06 + 0.04 (i - 1) m (contiguous elements;
    eq. 1 puts receiver i at +d_i along track). Phase-centre spacing 0.02 m = D_rx/2 and
    V PRI = 0.64 m = 32 x 0.02 m: critically sampled. Assumed (not in the paper): pulse length
    10 ms, sampling rate 25 kHz (1.25 B), c = 1500 m/s, platform at depth 0 (2-D geometry).
    """
    return _line_array_sonar(Array.uniform_line(32, 0.04, first=0.06, tx_length=0.08, rx_length=0.04),
                             Waveform(f0=150e3, bandwidth=20e3, duration=10e-3, fs=25e3),
                             speed=2.0, prf=1 / 0.32, n_pulses=n_pulses)


def wu2018(n_pulses: int = 128) -> Scenario:
    """Wu, Tang & Zhong 2018, Table 1: f0 = 70 kHz, pulse 20 ms, PRF 2.3436 Hz, B = 10 kHz,
    V = 3 m/s, hydrophone 0.08 m, range sampling 20 kHz, transmitter 0.16 m, 32 hydrophones.

    Hydrophones at d_i = [i - (N + 1)] 0.08 m for i = 1..32 with N = 15 (section 2.1: the
    (N+1)th shares the transmitter's position; 32 hydrophones make the array one element
    longer ahead). V / PRF = 1.28 m = 32 x 0.04 m phase-centre spacing: critically sampled.
    The table prints PRF 2.3436 Hz; 3 / 1.28 = 2.34375 Hz is used so that V / PRF is exactly
    1.28 m (the printed value gives a 40.08 mm gap against D/2 = 40 mm and would warn).
    Assumed: c = 1500 m/s, platform at depth 0. Yaw/pitch errors are added by the caller
    (the paper draws them at random in 1-2 degrees).
    """
    return _line_array_sonar(Array.uniform_line(32, 0.08, first=-15 * 0.08, tx_length=0.16, rx_length=0.08),
                             Waveform(f0=70e3, bandwidth=10e3, duration=20e-3, fs=20e3),
                             speed=3.0, prf=3.0 / 1.28, n_pulses=n_pulses)


def wu2018_inclined(n_pulses: int = 64, height: float = 30.0, seed: int | None = 2018, yaw: bool = True,
                    pitch: bool = True, low_deg: float = 1.0, high_deg: float = 2.0) -> Scenario:
    """Wu, Tang & Zhong 2018 section 3.3: the Table 1 sonar (:func:`wu2018`), five points at
    slant ranges and along-track positions P1 (297, -3), P2 (303, -3), P3 (303, 3), P4 (297, 3),
    P5 (300, 0) m, and yaw and pitch drawn at random in [``low_deg``, ``high_deg``] degrees for
    every pulse (Fig. 5: "random between 1 and 2 degrees"; ``yaw`` / ``pitch`` False keeps that
    angle at zero; ``seed`` the generator's seed, None for a fresh draw).

    Assumed (not in the paper): the array flies ``height`` = 30 m above the seafloor (the h of
    eq. 3; the points lie on it, so their ground ranges are sqrt(r^2 - h^2)); each pulse's
    angles are the attitude when its echoes arrive (2 x 300 m / c after emission), a cubic
    spline joining them (so the attitude is smooth: it changes by ~0.02 deg between the
    nearest and the farthest point's echoes); the pulses are centred on
    eta = 0, so the targets' apertures (about 40 m at 300 m) lie inside the record for
    ``n_pulses`` >= 40.
    """
    base = wu2018(n_pulses=n_pulses)
    c = base.medium.sound_speed
    schedule = PulseSchedule(prf=base.schedule.prf, n_pulses=n_pulses)
    eta = schedule.eta
    rng = np.random.default_rng(seed)
    angles = {name: np.deg2rad(rng.uniform(low_deg, high_deg, n_pulses)) if on else np.zeros(n_pulses)
              for name, on in (("yaw", yaw), ("pitch", pitch))}
    # the drawn angles at each pulse's reception, one extra pulse either side for the spline's ends
    times = eta[0] - 1 / schedule.prf + 2 * 300.0 / c + np.arange(n_pulses + 2) / schedule.prf
    sampled = {name: np.concatenate([values[:1], values, values[-1:]]) for name, values in angles.items()}
    platform = Platform(speed=base.platform.speed, yaw=sampled["yaw"], pitch=sampled["pitch"],
                        error_times=times)
    points = np.array([[np.sqrt(r * r - height * height), y, -height]
                       for r, y in ((297.0, -3.0), (303.0, -3.0), (303.0, 3.0), (297.0, 3.0), (300.0, 0.0))])
    return base.replace(platform=platform, schedule=schedule, targets=(PointTargets(points),))


def zhang2019(n_pulses: int = 256, receivers: int = 30, pri: float = 0.3) -> Scenario:
    """Zhang, Tan & Ying 2019, Table 1: f0 = 150 kHz, B = 20 kHz, V = 2 m/s, receiver length
    0.02 m, receiver array 0.6 m (30 receivers), transmitter 0.04 m, PRI 0.3 s.

    As printed, the table undersamples the aperture: 30 phase centres 0.01 m apart cover
    0.3 m per ping while the platform moves V PRI = 0.6 m, so the Scenario warns
    (SamplingWarning). The preset keeps the printed values by default. Receivers ahead of the
    transmitter at d_i = 0.03 + (0.6 / ``receivers``) (i - 1) m (contiguous for 30). Assumed:
    pulse 10 ms, sampling rate 25 kHz, c = 1500 m/s, platform at depth 0.

    ``receivers`` and ``pri`` change what the table cannot have meant together. The
    reproduction (``clsas reproduce zhang2019``) uses ``receivers=30, pri=0.15``: the printed
    0.6 m array of contiguous 0.02 m receivers (30 of them), and PRI 0.15 s so that
    V PRI = 0.3 m = the span of the 30 phase centres (0.01 m apart, uniform across pings, as
    the coherent superposition of section 4.4 needs). The equivalent sampling rate
    M PRF = 200 Hz holds the transmitter's beam up to its first null (|f_t| <= 2 V / D_tx =
    100 Hz). An earlier choice, 15 receivers on a 0.04 m pitch with M PRF = 100 Hz, folds the
    beam between 50 and 100 Hz into the processed band: PTRS and PCA then lose ISLR against
    back-projection (which integrates only |f_t| <= 50 Hz) whatever the sub-block width, and
    far less with 30 receivers.
    """
    spacing = 0.6 / receivers
    return _line_array_sonar(Array.uniform_line(receivers, spacing, first=0.03, tx_length=0.04, rx_length=0.02),
                             Waveform(f0=150e3, bandwidth=20e3, duration=10e-3, fs=25e3),
                             speed=2.0, prf=1 / pri, n_pulses=n_pulses)


def heremans2009(n_pulses: int = 128) -> Scenario:
    """Heremans, Dupont & Acheroy 2009, section 5.2: 15 hydrophones 21.88 cm apart, the
    transmitter in the middle (shared with hydrophone 8), v = 1.2763 m/s, PRT 0.6 s,
    f0 = 50 kHz (lambda = 3 cm, section 5.5.3).

    v PRT = 0.7658 m = 7 phase-centre spacings (eq. 50 with H = 15, n = 8 overlapping phase
    centres). Assumed (not in the chapter): B = 10 kHz, pulse 10 ms, sampling rate 12.5 kHz,
    element lengths 21.88 cm (contiguous), c = 1500 m/s, platform at depth 0.
    """
    spacing = 0.2188
    return _line_array_sonar(Array.uniform_line(15, spacing, first=-7 * spacing, tx_length=spacing, rx_length=spacing),
                             Waveform(f0=50e3, bandwidth=10e3, duration=10e-3, fs=12.5e3),
                             speed=1.2763, prf=1 / 0.6, n_pulses=n_pulses)


SONARS = {
    "kiang2022": kiang2022,
    "huang2022": huang2022,
    "wu2018": wu2018,
    "zhang2019": zhang2019,
    "heremans2009": heremans2009,
}


def sonar(name: str = "kiang2022", **options) -> Scenario:
    """The named paper's sonar as a Scenario (see the module docstring for the names)."""
    if name not in SONARS:
        raise ValueError(f"unknown sonar preset {name!r}; known: {sorted(SONARS)}")
    return SONARS[name](**options)


def _grid(ranges, along) -> np.ndarray:
    return np.array([[x, y, 0.0] for x in ranges for y in along])


# Zhang et al. 2019 Tables 2-4: the sub-block width each of T1-T6 (and T7-T12) measures, m
ZHANG_WIDTHS = (20.0, 14.0, 12.0, 10.0, 8.0, 2.0)
ZHANG_REFERENCES = (53.0, 143.0, 194.0)

# Point-target layouts (x across track, y along track, z = 0 at the platform's depth), m.
POINT_LAYOUTS = {
    # Huang & Yang 2022 Fig. 4 shows six points T1..T6 but the text gives no coordinates:
    # assumed two along-track rows (y = -2, +2 m) at ranges 40, 60, 80 m.
    "huang2022": _grid([40.0, 60.0, 80.0], [-2.0, 2.0]),
    # Zhang et al. 2019 Fig. 7 and section 6.1.2: 18 points in three groups decoupled at the
    # reference ranges 53, 143 and 194 m; "the difference between the target range and reference
    # range denotes the half width of the sub-block", so each point sits half a sub-block width
    # (20, 14, 12, 10, 8, 2 m for T1-T6 and T7-T12; 2, 8, 10, 12, 14, 20 m for T13-T18, the
    # order of Tables 2-4 and Figs. 8-10) from its group's reference. Assumed (not in the
    # text): the points alternate below and above the reference range, at y = -5, -3, -1, 1, 3, 5 m.
    "zhang2019": np.array([[ref + sign * width / 2, y, 0.0]
                           for ref, widths in zip(ZHANG_REFERENCES, (ZHANG_WIDTHS, ZHANG_WIDTHS, ZHANG_WIDTHS[::-1]))
                           for width, sign, y in zip(widths, (-1, 1, -1, 1, -1, 1), (-5.0, -3.0, -1.0, 1.0, 3.0, 5.0))]),
    # Wu et al. 2018 section 4: P1(297, -3), P2(303, -3), P3(303, 3), P4(297, 3), P5(300, 0) m.
    "wu2018": np.array([[297.0, -3.0, 0.0], [303.0, -3.0, 0.0], [303.0, 3.0, 0.0], [297.0, 3.0, 0.0],
                        [300.0, 0.0, 0.0]]),
    # Heremans et al. 2009 Fig. 10: nine points around the scene centre r0 = 100 m; offsets not
    # in the text: assumed a 3 x 3 grid, r = 95, 100, 105 m, u = -5, 0, 5 m.
    "heremans2009": _grid([95.0, 100.0, 105.0], [-5.0, 0.0, 5.0]),
}


def point_scene(name: str, n_pulses: int | None = None, **options) -> Scenario:
    """The named paper's sonar with its point targets (stationary, reflectivity 1).

    ``name`` is one of :data:`POINT_LAYOUTS` (huang2022: 6 points, 32 receivers; zhang2019:
    18 points; wu2018: 5 points; heremans2009: 9 points around r0 = 100 m, 15 hydrophones).
    ``n_pulses`` and ``options`` go to the sonar preset.
    """
    if name not in POINT_LAYOUTS:
        raise ValueError(f"unknown point scene {name!r}; known: {sorted(POINT_LAYOUTS)}")
    if n_pulses is not None:
        options["n_pulses"] = n_pulses
    scenario = SONARS[name](**options)
    layout = POINT_LAYOUTS[name] + np.array([0.0, 0.0, scenario.platform.start[2]])
    return scenario.replace(targets=(PointTargets(layout),))


def heremans2009_seafloor(n_pulses: int = 32, altitude: float = 15.0, sediment: str = "sand",
                          extent=(88.0, 112.0, -20.0, 20.0), point_ts_db: float = -20.0, seed: int = 5) -> Scenario:
    """Heremans et al. 2009's DPCA scene on a seafloor: the chapter's sonar (:func:`heremans2009`,
    platform at z = 0), a flat seafloor ``altitude`` m below it over ``extent`` (x_min, x_max,
    y_min, y_max, m) of ``sediment`` with its speckle facets (seeded by ``seed``; APL-UW law),
    and the nine points of :func:`point_scene` laid on it, of target strength ``point_ts_db``
    (reflectivity 10^(TS / 20)).

    Assumed (the chapter gives neither): the altitude (15 m: grazing 8.5 deg at r0 = 100 m,
    where sand backscatters about -36 dB), a sand floor, the extent (the one DPCA correlated
    over in ``clsas reproduce heremans2009``'s random-point floor) and TS = -20 dB (about 40 dB
    above a resolution cell of the floor). Facets: one per ~4.5 cm (four per 7.5 cm x 10.9 cm
    resolution cell), about 0.5 million over the default extent.
    """
    from .. import validate as v

    altitude = v.positive("heremans2009_seafloor altitude", altitude, high=1e4, unit="m")
    ts = v.scalar("heremans2009_seafloor point_ts_db", point_ts_db, low=-150.0, high=60.0, unit="dB")
    scene = point_scene("heremans2009", n_pulses=n_pulses)
    layout = POINT_LAYOUTS["heremans2009"] + np.array([0.0, 0.0, scene.platform.start[2] - altitude])
    points = PointTargets(layout, reflectivity=10 ** (ts / 20))
    floor = Seafloor(extent, scene.platform.start[2] - altitude, sediment=sediment, seed=seed)
    return scene.replace(targets=(points,), seafloor=floor)


def mine_scene(n_pulses: int = 320, altitude: float = 8.0, sediment: str = "sand", seed: int = 0,
               object_sigma_db: float = -5.0, max_facet: float = 0.03) -> Scenario:
    """The classic mine-like scene: a cylinder and a truncated cone on rippled sand.

    Sonar (assumed, a typical high-frequency SAS): one transceiver with a 10 cm element at
    z = 0, 100 kHz, 20 kHz band (c / 2B = 3.75 cm), 2 ms chirp sampled at 25 kHz, 1 m/s and
    20 pulses/s (a D / 2 = 5 cm step), ``n_pulses`` centred on y = 0 (320: a 16 m track).
    Seafloor ``altitude`` m below: ``sediment`` (APL-UW law) with ripples 4 cm high, 0.5 m
    long, their crests 20 deg off the track, over x in [20, 34] m, y in [-6, 6] m, speckle
    seeded by ``seed``. Objects lying on it: a cylinder 2 m long and 0.53 m in diameter at
    (25, -2.5) m, its axis 20 deg off the track; a truncated cone 1 m across its base, 0.5 m at
    its top, 0.45 m high at (29, 2) m. Their facets (at most ``max_facet`` m on a side) are
    Lambertian with random phases (rough surfaces), scaled so that they backscatter
    ``object_sigma_db`` per unit area (-5 dB: about 20 dB above the sand at these grazing
    angles). Image it with ``clsas.backproject`` on the plane z = -altitude, or ``clsas.omega_k``
    of ``clsas.line_record`` (slant range).
    """
    from .. import validate as v
    from .hulls import cylinder, truncated_cone
    from .targets import MeshTarget

    n_pulses = v.integer("mine_scene n_pulses", n_pulses, low=2, high=10**6)
    altitude = v.positive("mine_scene altitude", altitude, high=1e3, unit="m")
    sigma = 10 ** (v.scalar("mine_scene object_sigma_db", object_sigma_db, low=-100.0, high=40.0, unit="dB") / 10)
    floor_z = -altitude
    objects = []
    for mesh, position, heading, seed_k in (
            (cylinder(0.265, 2.0, 48, segments=40), (25.0, -2.5, floor_z + 0.265), np.pi / 2 + np.deg2rad(20.0), 1),
            (truncated_cone(0.5, 0.25, 0.45, 48), (29.0, 2.0, floor_z), 0.0, 2)):
        shaped = MeshTarget(mesh, max_facet=max_facet)
        area = shaped.mesh.area_faces
        gain = float(np.sqrt(sigma * area.sum() / np.sum(area * area)))  # sum gain^2 A^2 = sigma x the area
        objects.append(MeshTarget(shaped.mesh, position=position, heading=heading, speckle_seed=seed + seed_k,
                                  gain=gain))
    floor = Seafloor((20.0, 34.0, -6.0, 6.0), floor_z, sediment=sediment, ripple_wavelength=0.5, ripple_height=0.04,
                     ripple_direction=np.deg2rad(20.0), seed=seed)
    return Scenario(Medium(1500.0), Waveform(f0=100e3, bandwidth=20e3, duration=2e-3, fs=25e3), Platform(speed=1.0),
                    Array(rx_offsets=[[0.0, 0.0, 0.0]], tx_length=0.1, rx_length=0.1),
                    PulseSchedule(prf=20.0, n_pulses=n_pulses), targets=tuple(objects), seafloor=floor)


# Kiang & Kiang 2022 section II-B: the Albacore model (LOA 62.13 m) scaled down six times, LOA ~10 m.
KIANG_HULL_SCALE = 1.0 / 6.0

# Kiang & Kiang 2022 Table II: the submarine's velocity vector (m/s) in the eight cases.
KIANG_CASES = {
    1: (0.0, -4.0, 0.0), 2: (0.0, 4.0, 0.0), 3: (0.0, -5.0, 3.0), 4: (0.0, -5.0, -3.0),
    5: (1.5, 8.0, 1.0), 6: (3.0, -5.0, 3.0), 7: (0.0, 3.0, 0.0), 8: (3.0, 0.0, 0.0),
}


def kiang2022_case(case: int, n_pulses: int | None = None, max_facet: float | None = None,
                   sections: int = 64, stations: int = 80) -> Scenario:
    """Kiang & Kiang 2022 case ``case`` (1-8, Table II): the Table I sonar (transceiver A, towed
    receiver B, sonobuoy C at (-500, 0, -150) m) and the submarine centred at (1989, 0, -350) m at
    eta = 0, moving with the case's velocity vector.

    The hull is the Albacore model scaled down six times (section II-B: LOA about 10 m;
    :data:`KIANG_HULL_SCALE`): 10.35 m long, 1.4 m in diameter.

    The bow points along the velocity (the paper: "the bow is oriented toward" the motion):
    heading = atan2(v_y, v_x), pitch = atan2(v_z, |v_xy|) (assumed; the paper shows the
    orientation only in its figures). ``max_facet`` subdivides the hull (m); ``sections`` and
    ``stations`` set its base facet count (:func:`clsas.scene.hulls.submarine`).
    """
    from .hulls import submarine
    from .targets import MeshTarget

    if case not in KIANG_CASES:
        raise ValueError(f"case must be one of {sorted(KIANG_CASES)} (Kiang & Kiang 2022 Table II), got {case!r}")
    v = np.array(KIANG_CASES[case])
    mesh = submarine(sections=sections, stations=stations)
    mesh.apply_scale(KIANG_HULL_SCALE)
    hull = MeshTarget(mesh, position=(1989.0, 0.0, -350.0),
                      heading=float(np.arctan2(v[1], v[0])), pitch=float(np.arctan2(v[2], np.hypot(v[0], v[1]))),
                      velocity=v, max_facet=max_facet)
    return kiang2022(n_pulses=n_pulses).replace(targets=(hull,))
