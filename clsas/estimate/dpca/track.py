"""The trajectory integrated from the ping pairs (eqs. 71-73), imaging along it, and the motion
compensation of the records (eqs. 74-75)."""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import scipy.fft

from ... import budget, validate
from ...image.rangecomp import check_workers
from ...model import EchoData
from ...scene.scenario import Array, Platform, Scenario
from .geometry import pairing, scenario_extent
from .pairs import PingPairs

log = logging.getLogger("clsas")


@dataclass(frozen=True, eq=False)
class Trajectory:
    """The track integrated from the ping pairs (eqs. 71-73), relative to the first ping.

    eta : s (n_pulses,); along, cross : m, the platform's reference point relative to the
    nominal straight track and to its place at the first ping (along: beyond v eta, i.e.
    surge; cross: towards +x, i.e. sway), at :attr:`times`; heading : rad (yaw, from heading0
    at the first ping), at :attr:`heading_times`; along_std, cross_std, heading_std :
    propagated standard errors (eq. 73: random walks of the per-pair errors); pairs : the
    PingPairs; heading_bias : rad, how far the heading may have drifted by the per-pair yaw
    bias bound (PingPairs.yaw_bias, the same sign every pair: it grows linearly), None when
    not known.
    """

    eta: np.ndarray
    along: np.ndarray
    cross: np.ndarray
    heading: np.ndarray
    along_std: np.ndarray
    cross_std: np.ndarray
    heading_std: np.ndarray
    pairs: PingPairs
    heading_bias: np.ndarray | None = None

    @property
    def times(self) -> np.ndarray:
        """When the track holds these values, s: each ping's emission plus half the two-way
        travel time to the scene. DPCA compares transmit-and-receive paths, so it measures the
        mean of the platform's place at emission and at reception."""
        return self.eta + self.pairs.two_way / 2

    @property
    def heading_times(self) -> np.ndarray:
        """When :attr:`heading` holds, s: each ping's reception (emission plus the two-way
        time). A phase centre sits at (o_tx sin(yaw at emission) + o_h sin(yaw at reception)) / 2
        across track; its part that changes along the couples, the yaw DPCA reads, is the
        hydrophones' at reception (the transmitter's is common to the couples and enters the
        sway). Read at mid-time instead, the -D theta_p term of :func:`integrate` is off by
        D theta' tau / 2, a sway error of v tau / 2 = 8.5 cm times the yaw step at Heremans'
        geometry (30 urad a pair for 3 mrad / 30 s of yaw)."""
        return self.eta + self.pairs.two_way

    def trusted(self, heading: float, cross: float | None = None) -> int:
        """How many pings from the first the track can be trusted: the pings before the
        heading's standard error (a random walk of the per-pair yaw errors, eq. 73) plus its bias
        bound (:attr:`heading_bias`) first exceeds ``heading`` rad, and, if given, the
        cross-track position's standard error exceeds ``cross`` m.
        Both grow along the track: heading_std as sqrt(p) for equal per-pair errors, cross_std
        as p^1.5 (the heading errors integrated once more)."""
        limit = validate.positive("Trajectory.trusted heading", heading, unit="rad")
        bias = 0.0 if self.heading_bias is None else self.heading_bias
        over = self.heading_std + bias > limit
        if cross is not None:
            over |= self.cross_std > validate.positive("Trajectory.trusted cross", cross, unit="m")
        return int(np.argmax(over)) if over.any() else self.eta.size

    def platform(self, speed: float, start=(0.0, 0.0, 0.0), surge: bool = True) -> Platform:
        """A clsas Platform flying this track (for :func:`with_track` and back-projection):
        surge, sway and yaw at :attr:`times` (the heading carried there from
        :attr:`heading_times` by linear interpolation), held constant one ping interval beyond
        the first and the last so that every emission and reception is covered. ``surge=False``
        flies the nominal along-track advance instead of the estimated one (DPCA's surge is a
        random walk of its per-pair errors: on scenes with little seafloor it can hurt more
        than the surge it corrects)."""
        step = float(np.median(np.diff(self.eta)))
        times = np.concatenate([[self.times[0] - step], self.times, [self.times[-1] + step]])
        hold = lambda a: np.concatenate([[a[0]], a, [a[-1]]])  # noqa: E731
        along = self.along if surge else np.zeros_like(self.along)
        heading = np.interp(self.times, self.heading_times, self.heading)
        return Platform(speed=speed, start=start, surge=hold(along), sway=hold(self.cross),
                        yaw=hold(heading), error_times=times)


def integrate(pairs: PingPairs, eta: np.ndarray, speed: float, array: Array, heading0: float = 0.0) -> Trajectory:
    """The platform track from the ping pairs (eqs. 71-72) and its errors (eq. 73), relative to
    the first ping; positions of the platform's reference point (its centre of rotation).

    DPCA measures changes of heading only: ``heading0`` (rad) is the yaw at the first ping, from
    the vehicle's compass or INS. An error e in it tilts the whole track by e (a cross-track
    drift of D e a ping), which rotates the image slightly but does not defocus it.

    Derivation (clsas's axes and Platform.rotation: a body offset b along the track sits at
    b sin(yaw) across track). Couple n pairs hydrophone j at ping p with hydrophone i at ping
    p + 1, body phase-centre offsets pc_j = pc_i + D (D = v PRT). Its measured cross-track
    displacement is gamma_n = X_{p+1} - X_p + pc_i sin(theta_{p+1}) - pc_j sin(theta_p)
    = dX_p + pc_i xi_p - D theta_p (small angles), so the slope along the couples is the yaw
    step xi_p, and at the couples' centre u (mean pc_i) the sway reads gamma_p = dX_p + u xi_p
    - D theta_p, X at mid-time and theta at reception (see Trajectory.heading_times). Hence
        theta_{p+1} = theta_p + xi_p,
        X_{p+1} = X_p + gamma_p - u xi_p + D theta_p,
        Y_{p+1} = Y_p + D + surge_p,
    which is eq. (71) written for the centre of rotation instead of the phase-centre group.
    Errors accumulate as in eq. (73): var X_p = sum_l var gamma_l + sum_l (D (p - l - 1) - u)^2
    var xi_l (the yaw of pair l enters through theta for every later pair), var theta_p =
    sum_l var xi_l.
    """
    if not isinstance(pairs, PingPairs):
        raise TypeError(f"dpca.integrate pairs: must be the PingPairs of dpca.estimate, got {type(pairs).__name__}")
    if not isinstance(array, Array):
        raise TypeError(f"dpca.integrate array: must be a clsas Array (the hydrophone layout), got {type(array).__name__}")
    eta = validate.array("dpca.integrate eta", eta, (pairs.sway.size + 1,), bound=validate.MAX_COORDINATE)
    prt = np.diff(eta)
    if eta.size < 2 or not np.all(prt > 0) or not np.allclose(prt, prt[0], rtol=1e-6):
        raise ValueError("dpca.integrate eta: must be emission times at a constant pulse interval, increasing, got "
                         f"intervals {prt.min() if prt.size else None:g} .. {prt.max() if prt.size else None:g} s")
    speed = validate.positive("dpca.integrate speed", speed, unit="m/s", why="the nominal platform speed")
    heading0 = validate.scalar("dpca.integrate heading0", heading0, low=-0.5, high=0.5, unit="rad")
    prf = 1.0 / float(np.median(prt))
    s, pc, n_couples = pairing(array, speed, prf, pairs.lags)
    u = pc[:n_couples].mean()
    d = speed / prf
    heading = heading0 + np.concatenate([[0.0], np.cumsum(pairs.yaw)])
    cross = np.concatenate([[0.0], np.cumsum(pairs.sway - u * pairs.yaw + d * heading[:-1])])
    along = np.concatenate([[0.0], np.cumsum(pairs.surge)])
    n = eta.size
    p = np.arange(n)[:, None]
    l_ = np.arange(n - 1)[None, :]
    before = (l_ < p).astype(np.float64)
    arm = before * (d * (p - l_ - 1) - u)
    cross_std = np.sqrt(before @ pairs.sway_std**2 + arm**2 @ pairs.yaw_std**2)
    heading_std = np.sqrt(before @ pairs.yaw_std**2)
    along_std = np.sqrt(before @ pairs.surge_std**2)
    per_pair = np.zeros(n - 1) if pairs.yaw_bias is None else np.abs(pairs.yaw_bias)
    heading_bias = np.concatenate([[0.0], np.cumsum(per_pair)])
    log.info("dpca.integrate: over %d pings the heading's standard error grows to %.3g urad (a random walk of "
             "%.3g urad RMS a pair), its bias bound to %.3g urad; the cross-track position's standard error to "
             "%.3g mm", n, heading_std[-1] * 1e6, float(np.sqrt(np.mean(pairs.yaw_std**2))) * 1e6,
             heading_bias[-1] * 1e6, cross_std[-1] * 1e3)
    return Trajectory(eta=eta, along=along, cross=cross, heading=heading, along_std=along_std, cross_std=cross_std,
                      heading_std=heading_std, pairs=pairs, heading_bias=heading_bias)


def with_track(echo: EchoData, scenario: Scenario) -> EchoData:
    """``echo`` with its geometry (transmitter at emission, receiver nodes) recomputed for the
    sonar and platform of ``scenario`` (e.g. a Platform from :meth:`Trajectory.platform`), so that
    :func:`clsas.backproject` images along that track; the samples are unchanged."""
    if scenario.n_receivers != echo.n_rx or scenario.eta.shape != echo.eta.shape or \
            not np.allclose(scenario.eta, echo.eta):
        raise ValueError("with_track: the scenario must have the echo's receivers and emission times")
    tx = scenario.tx_position(echo.eta)
    t = echo.eta[None, :, None] + echo.rx_tau[:, None, :]
    rx = np.stack([scenario.receiver_position(h, t[h]) for h in range(echo.n_rx)])
    return echo.replace(tx_pos=tx, rx_pos=rx, provenance={**echo.provenance, "track": "replaced (dpca.with_track)"})


DELAY_BYTES = 48  # bytes delay_records holds a sample: the spectra, the phase ramp in complex128 and its argument, the copy


def delay_records(data: np.ndarray, dt: np.ndarray, f0: float, fs: float, workers: int | None = -1) -> np.ndarray:
    """Baseband records ``data`` (complex, (n_rx, n_pulses, n_samples), carrier ``f0`` Hz,
    sampled at ``fs`` Hz) with receiver h's ping p delayed by ``dt[h, p]`` s (negative: advanced):
    the phase exp(-j 2 pi (f0 + f) dt) over the baseband frequencies f of each ping, i.e. the
    envelope shifted by dt (circularly: dt must stay well inside the record's margins) and the
    carrier's phase turned by -2 pi f0 dt. complex64, the shape of ``data``."""
    data = np.asarray(data)
    if data.ndim != 3 or data.dtype.kind not in "fc":
        raise ValueError(f"delay_records data: must be complex records (n_rx, n_pulses, n_samples), got shape "
                         f"{data.shape} of {data.dtype}")
    if data.shape[-1] < 1:
        raise ValueError(f"delay_records data: the records must hold at least one sample, got shape {data.shape}")
    dt = np.asarray(dt, dtype=np.float64)
    if dt.shape != data.shape[:2]:
        raise ValueError(f"delay_records: dt must have shape (n_rx, n_pulses) = {data.shape[:2]} of data "
                         f"(n_rx, n_pulses, n_samples), got dt {dt.shape} and data {data.shape}")
    if not np.all(np.isfinite(dt)):
        raise ValueError("delay_records: dt must be finite seconds")
    f0 = validate.scalar("delay_records f0", f0, low=0.0, unit="Hz")
    fs = validate.positive("delay_records fs", fs, unit="Hz")
    f = scipy.fft.fftfreq(data.shape[-1], 1 / fs)
    spec = scipy.fft.fft(data, axis=-1, workers=workers)
    spec *= np.exp(-2j * np.pi * (f0 + f)[None, None, :] * dt[..., None])
    return scipy.fft.ifft(spec, axis=-1, workers=workers).astype(np.complex64)


def compensate(echo: EchoData, trajectory: Trajectory, scenario: Scenario, workers: int | None = -1,
               depth: float | str | None = "auto") -> EchoData:
    """Motion compensation of eqs. (74)-(75): each hydrophone's record delayed back by
    dt = dt_sway + dt_yaw{h} (eqs. 34, 38: dt_sway = -2 sway / c, dt_yaw{h} = -(o_h - o_tx) sin(yaw) / c,
    the receiver's cross-track move under yaw with the transmitter at the centre of rotation), by
    the phase exp(+j 2 pi (f0 + f) dt) over the record's baseband frequencies f (:func:`delay_records`
    by -dt); the geometry is
    replaced by the nominal straight track of ``scenario`` so that omega_k, range_doppler and
    chirp_scaling accept the result. Surge (along-track) is not corrected by this delay model.
    The delay is exact at broadside only: a cross-track error x moves the two-way path to a
    scatterer at look angle theta by 2 x cos(theta), so 2 x (1 - cos theta) is left, 0.9 mm at
    the edge of Heremans' beam for 5 cm of sway (its cost in azimuth PSLR with the true track:
    tests/test_dpca.py). For omega_k / range_doppler /
    chirp_scaling, :func:`clsas.estimate.dpca.compensate_record` removes that residual over the
    beam on the interleaved record; back-projecting along the track (:func:`with_track` with
    :meth:`Trajectory.platform`) has no such residual. depth : m, z of the imaged plane, "auto"
    (default) or None: the track's moves across it are horizontal (as :func:`.pairs.estimate`
    returns them once it knows the seafloor's depth), and move the path to a scatterer seen at
    depression phi by their product with cos(phi), taken at the records' middle slant range (a
    scene 15 m below at 88-112 m: cos(phi) 0.986-0.991; the one value leaves 0.3 % of the sway at
    the swath's edges; the look angle's part, cos(theta) across the beam, is the broadside residual
    above). "auto": the z of the seafloor the echo's scenario holds, as ``estimate``'s
    ``extent="auto"`` reads it (:func:`.geometry.scenario_extent`), else None; None: the track's
    depth (a horizontal geometry, cos(phi) = 1)."""
    h = scenario.array.n_receivers
    if trajectory.eta.shape != echo.eta.shape:
        raise ValueError("compensate: the trajectory must have one value per ping of the echo")
    workers = check_workers(workers, "compensate workers")
    c = echo.medium.sound_speed
    lever = scenario.array.rx_offsets[:, 1] - scenario.array.tx_offset[1]
    dt = (-2 * trajectory.cross[None, :] - lever[:, None] * np.sin(trajectory.heading)[None, :]) / c  # (h, pulse)
    if isinstance(depth, str):
        validate.choice("compensate depth", depth, ("auto",))
        extent = scenario_extent(echo.scenario)
        depth = None if extent is None else extent.z
    if depth is not None:
        depth = validate.scalar("compensate depth", depth, low=-validate.MAX_COORDINATE, high=validate.MAX_COORDINATE,
                                unit="m")
        r_mid = c * (float(np.median(echo.t0[:h])) + echo.n_samples / (2 * echo.fs)) / 2
        below = (float(np.median(echo.tx_pos[:, 2])) - depth) / r_mid
        if not abs(below) < 1.0:
            raise ValueError(f"compensate depth: the plane z = {depth:g} m lies {abs(below) * r_mid:.4g} m from the track, "
                             f"beyond the records' mid range {r_mid:.4g} m; give the z of a plane the beam reaches")
        dt = dt * np.sqrt(1 - below**2)
    per_ping = echo.n_pulses * echo.n_samples  # the copy (complex64, 8 bytes a sample) and delay_records' work
    budget.check_bytes(f"compensate of {h} hydrophones x {echo.n_pulses} pings x {echo.n_samples} samples",
                       8 * echo.n_rx * per_ping + DELAY_BYTES * h * per_ping, "fewer pings or samples at a time")
    data = echo.data.copy()
    data[:h] = delay_records(echo.data[:h], -dt, echo.waveform.f0, echo.fs, workers)
    straight = scenario.replace(platform=Platform(speed=scenario.platform.speed, start=scenario.platform.start))
    out = with_track(echo.replace(data=data), straight)
    return out.replace(provenance={**echo.provenance, "motion_compensation": "dpca (Heremans et al. 2009, eqs. 74-75)"})
