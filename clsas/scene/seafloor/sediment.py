"""Sediments: the seabed's reflection coefficient and its backscattering strength.

A :class:`Sediment` holds the geoacoustic and roughness parameters of the APL-UW
High-Frequency Ocean Environmental Acoustic Models Handbook (APL-UW TR 9407, 1994, section IV,
"bottom"; the model is D. R. Jackson's, Jackson, Winebrenner & Ishimaru, JASA 79, 1986, and
Mourad & Jackson, Oceans '89): the density ratio rho (sediment / water), the sound-speed ratio
nu, the loss parameter delta (imaginary / real part of the sediment's wavenumber), the
exponent gamma2 and strength w2 of the interface roughness spectrum, and the volume parameter
sigma2 (the ratio of the sediment's volume scattering coefficient to its attenuation
coefficient). :data:`SEDIMENTS` holds the handbook's values for rock, gravel, sands and mud.

Notation: theta is the grazing angle (rad, from the mean plane), k = 2 pi f / c_w the water
wavenumber, kappa = (1 + i delta) / nu the complex wavenumber ratio and
P(theta) = sqrt(kappa^2 - cos^2 theta) (the branch with Im P >= 0, decaying into the bed).

Reflection (fluid, lossy: the Rayleigh coefficient)::

    V(theta) = (rho sin theta - P) / (rho sin theta + P)

Backscattering cross-section per unit area and solid angle, sigma (strength 10 log10 sigma, dB):

- ``"lambert"``: sigma = mu sin^2 theta (Lambert's law; Mackenzie, JASA 33, 1961). The
  sediment's ``lambert_mu_db`` (10 log10 mu), or when None the least-squares fit of the
  physical model's strength over 10-60 deg at the frequency asked.
- ``"apl"``: sigma = sigma_r + sigma_v, clsas's implementation of the parts of the APL-UW
  model named here:

  * small-roughness perturbation (first order, fluid-fluid, APL-94's sigma_pr)::

        sigma_pr = 4 k^4 sin^4 theta |Y|^2 W(2 k cos theta),
        Y = ((rho - 1)^2 cos^2 theta + rho^2 - kappa^2) / (rho sin theta + P)^2,
        W(K) = w2 / (h0 K)^gamma2   (h0 = 1 cm, w2 in cm^4: the handbook's units)

    (checked here against the bistatic form 1/4 k^4 |1 + V|^4 |G|^2 W of Williams & Jackson,
    JASA 103, 1998, at backscatter: the two agree algebraically, since 1 + V = 2 rho sin theta
    / (rho sin theta + P)). The handbook's composite-roughness average of sigma_pr over
    large-scale slopes is *not* applied: it smooths the peak at the critical angle and
    raises sigma below ~5 deg.
  * Kirchhoff approximation for the power-law roughness (APL-94's sigma_kr), near normal
    incidence::

        sigma_kr = b q_c |V(pi/2)|^2 / (8 pi (cos^(4 alpha) theta + a q_c^2 sin^4 theta)^((1 + alpha) / (2 alpha))),
        alpha = gamma2 / 2 - 1, C_h^2 = 2 pi w2' Gamma(2 - alpha) 2^(-2 alpha) / (alpha (1 - alpha) Gamma(1 + alpha)),
        q_c = C_h^2 2^(1 - 2 alpha) k^(2 (1 - alpha)),
        a = (8 alpha^2 Gamma((1 + alpha) / (2 alpha)) / (Gamma(1/2) Gamma(1/alpha) Gamma(1/(2 alpha))))^(2 alpha),
        b = a^(1/2 + 1/(2 alpha)) Gamma(1/alpha) / (2 alpha)

    with w2' = w2 1e-8 / h0^gamma2 the spectral strength in SI units (m^(4 - gamma2)), so that
    W(K) = w2' / K^gamma2.
  * the roughness term sigma_r = f sigma_kr + (1 - f) sigma_pr with f the cubic smoothstep from
    0 at 60 deg to 1 at 75 deg (clsas's choice, not the handbook's: perturbation theory fails
    near normal incidence, where W(2 k cos theta) diverges, the Kirchhoff term fails at low
    angles, and for the table's sands and gravel the two meet between 60 and 75 deg). Below
    60 deg sigma_r = sigma_pr, above 75 deg sigma_r = sigma_kr.
  * sediment volume scattering (APL-94's sigma_v)::

        sigma_v = 5 delta sigma2 |1 + V|^4 / (ln(10) rho^2 Im P)

    Derivation: the transmitted pressure is (1 + V), it decays as exp(-k Im P z) with depth z
    each way, so the depth integral of the scattered intensity is 1 / (4 k Im P); the volume
    scattering coefficient is sigma2 times the sediment's attenuation in dB per metre,
    (20 / ln 10) k delta (the handbook's definition of sigma2, with the 1 / nu of the
    sediment's wavenumber absorbed in Im P), which gives the factor 5 delta sigma2 / (ln 10
    Im P); the two water-sediment crossings give |1 + V|^4 / rho^2 (equal to the handbook's
    |1 - V^2|^2 sin^2 theta / |P|^2, since 1 - V = (1 + V) P / (rho sin theta)). Check: with
    rho = nu = 1 (water holding scatterers) it reduces to 5 sigma2 sin theta / ln 10, the
    half-space result sigma_vol sin theta / (4 alpha) with alpha the attenuation in Np/m.

delta is a ratio of wavenumbers, so V does not depend on frequency; sigma does through k.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ... import validate as v

LAWS = ("apl", "lambert")
H0 = 0.01  # m: the handbook's reference length of the roughness spectrum (1 cm)
FIT_DEG = (10.0, 60.0)  # grazing angles of Lambert's fit to the physical model, deg
CROSSOVER_DEG = (60.0, 75.0)  # sigma_pr below, sigma_kr above, a smoothstep between
MAX_FREQUENCY = 1e7  # Hz
REFERENCE_SOUND_SPEED = 1500.0  # m/s, the water's sound speed when none is given


@dataclass(frozen=True)
class Sediment:
    """A sediment: the parameters of the APL-UW model (see the module docstring).

    Parameters
    ----------
    name : str
        A label (the table's name, or your own).
    density_ratio : float
        rho, sediment / water density, in (0, 10].
    sound_speed_ratio : float
        nu, sediment / water sound speed, in (0, 10].
    loss : float
        delta, the loss parameter (imaginary / real wavenumber), in [0, 1].
    spectral_exponent : float
        gamma2 of the roughness spectrum W(K) = w2 / (h0 K)^gamma2, in (2, 4).
    spectral_strength : float
        w2, cm^4 (h0 = 1 cm), >= 0.
    volume_ratio : float
        sigma2, volume scattering / attenuation coefficient, >= 0.
    lambert_mu_db : float or None
        Lambert's parameter 10 log10 mu, dB in [-100, 0]; None fits it to the physical model
        (least squares over 10-60 deg at the frequency asked).
    """

    name: str = "custom"
    density_ratio: float = 1.845
    sound_speed_ratio: float = 1.1782
    loss: float = 0.01624
    spectral_exponent: float = 3.25
    spectral_strength: float = 0.004446
    volume_ratio: float = 0.002
    lambert_mu_db: float | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name:
            raise TypeError(f"Sediment.name: must be a non-empty string, got {self.name!r}")
        set_ = lambda k, val: object.__setattr__(self, k, val)  # noqa: E731
        set_("density_ratio", v.scalar("Sediment.density_ratio", self.density_ratio, low=0.0, low_open=True,
                                       high=10.0))
        set_("sound_speed_ratio", v.scalar("Sediment.sound_speed_ratio", self.sound_speed_ratio, low=0.0,
                                           low_open=True, high=10.0))
        set_("loss", v.scalar("Sediment.loss", self.loss, low=0.0, high=1.0))
        set_("spectral_exponent", v.scalar("Sediment.spectral_exponent", self.spectral_exponent, low=2.0, high=4.0,
                                           low_open=True, high_open=True))
        set_("spectral_strength", v.scalar("Sediment.spectral_strength", self.spectral_strength, low=0.0, high=1e3,
                                           unit="cm^4"))
        set_("volume_ratio", v.scalar("Sediment.volume_ratio", self.volume_ratio, low=0.0, high=1.0))
        if self.lambert_mu_db is not None:
            set_("lambert_mu_db", v.scalar("Sediment.lambert_mu_db", self.lambert_mu_db, low=-100.0, high=0.0,
                                           unit="dB"))

    @staticmethod
    def named(name: str) -> "Sediment":
        """The table's sediment ``name`` (:data:`SEDIMENTS`)."""
        if not isinstance(name, str) or name not in SEDIMENTS:
            raise ValueError(f"sediment: must be one of {tuple(SEDIMENTS)} or a Sediment, got {name!r}")
        return SEDIMENTS[name]

    # -- the model ---------------------------------------------------------------------------

    @property
    def kappa(self) -> complex:
        """kappa = (1 + i delta) / nu, the sediment / water complex wavenumber ratio."""
        return (1.0 + 1j * self.loss) / self.sound_speed_ratio

    def _p(self, cos: np.ndarray) -> np.ndarray:
        """P = sqrt(kappa^2 - cos^2 theta), Im P >= 0 (the principal root: Im(kappa^2) >= 0)."""
        p = np.sqrt(self.kappa ** 2 - cos * cos + 0j)
        return np.where(p.imag < 0, -p, p)

    def reflection_coefficient(self, grazing_rad, f_hz=None) -> np.ndarray:
        """The plane-wave reflection coefficient V(theta) of the flat water-sediment interface
        (complex, any shape of ``grazing_rad`` in [0, pi/2]); ``f_hz`` is checked and unused
        (delta is a constant-Q loss: V does not depend on frequency)."""
        theta = _grazing("Sediment.reflection_coefficient grazing_rad", grazing_rad)
        if f_hz is not None:
            _frequency("Sediment.reflection_coefficient f_hz", f_hz)
        return self._reflection(theta)

    def _reflection(self, theta: np.ndarray) -> np.ndarray:
        sin, cos = np.sin(theta), np.cos(theta)
        p = self._p(cos)
        return (self.density_ratio * sin - p) / (self.density_ratio * sin + p)

    def backscatter_strength_db(self, grazing_rad, f_hz, law: str = "apl", sound_speed: float | None = None):
        """10 log10 sigma (dB re 1 m^2 per m^2 and steradian) at the grazing angles
        ``grazing_rad`` (rad, [0, pi/2], any shape) and the frequency ``f_hz`` (Hz, scalar);
        ``law`` "apl" or "lambert" (module docstring); ``sound_speed`` of the water (m/s,
        default 1500). -inf where sigma is 0 (theta = 0)."""
        with np.errstate(divide="ignore"):
            return 10.0 * np.log10(self.backscatter_cross_section(grazing_rad, f_hz, law, sound_speed))

    def backscatter_cross_section(self, grazing_rad, f_hz, law: str = "apl", sound_speed: float | None = None):
        """sigma (linear, per unit area and steradian): see :meth:`backscatter_strength_db`."""
        theta = _grazing("Sediment.backscatter grazing_rad", grazing_rad)
        f = _frequency("Sediment.backscatter f_hz", f_hz)
        v.choice("Sediment.backscatter law", law, LAWS)
        c = REFERENCE_SOUND_SPEED if sound_speed is None else v.scalar(
            "Sediment.backscatter sound_speed", sound_speed, low=1000.0, high=2000.0, unit="m/s")
        k = 2.0 * np.pi * f / c
        if law == "lambert":
            return 10.0 ** (self._lambert_mu_db(k) / 10.0) * np.sin(theta) ** 2
        return self._apl(theta, k)

    def _lambert_mu_db(self, k: float) -> float:
        if self.lambert_mu_db is not None:
            return self.lambert_mu_db
        theta = np.deg2rad(np.linspace(*FIT_DEG, 51))
        return float(np.mean(10.0 * np.log10(self._apl(theta, k) / np.sin(theta) ** 2)))

    def _apl(self, theta: np.ndarray, k: float) -> np.ndarray:
        low, high = CROSSOVER_DEG
        u = np.clip((np.rad2deg(theta) - low) / (high - low), 0.0, 1.0)
        crossover = u * u * (3.0 - 2.0 * u)
        perturbation = np.where(crossover < 1.0, self._perturbation(np.minimum(theta, np.deg2rad(high)), k), 0.0)
        rough = crossover * self._kirchhoff(theta, k) + (1.0 - crossover) * perturbation
        return rough + self._volume(theta, k)

    def roughness_spectrum(self, wavenumber) -> np.ndarray:
        """W(K) = w2 / (h0 K)^gamma2, m^4, at horizontal wavenumbers K (rad/m, > 0)."""
        return self.spectral_strength * 1e-8 / (H0 * np.asarray(wavenumber, dtype=np.float64)) ** self.spectral_exponent

    def _perturbation(self, theta: np.ndarray, k: float) -> np.ndarray:
        sin, cos = np.sin(theta), np.cos(theta)
        rho = self.density_ratio
        y = ((rho - 1.0) ** 2 * cos * cos + rho * rho - self.kappa ** 2) / (rho * sin + self._p(cos)) ** 2
        with np.errstate(divide="ignore", invalid="ignore"):
            out = 4.0 * k ** 4 * sin ** 4 * np.abs(y) ** 2 * self.roughness_spectrum(2.0 * k * cos)
        return np.where(cos > 0, out, np.inf)

    def _kirchhoff(self, theta: np.ndarray, k: float) -> np.ndarray:
        alpha = self.spectral_exponent / 2.0 - 1.0
        w2 = self.spectral_strength * 1e-8 / H0 ** self.spectral_exponent  # SI: m^(4 - gamma2)
        ch2 = 2 * math.pi * w2 * math.gamma(2 - alpha) * 2 ** (-2 * alpha) / (alpha * (1 - alpha) * math.gamma(1 + alpha))
        qc = ch2 * 2 ** (1 - 2 * alpha) * k ** (2 * (1 - alpha))
        a = (8 * alpha ** 2 * math.gamma((1 + alpha) / (2 * alpha))
             / (math.gamma(0.5) * math.gamma(1 / alpha) * math.gamma(1 / (2 * alpha)))) ** (2 * alpha)
        b = a ** (0.5 + 1 / (2 * alpha)) * math.gamma(1 / alpha) / (2 * alpha)
        normal = abs(complex(self._reflection(np.array(np.pi / 2)))) ** 2
        cos4a = np.abs(np.cos(theta)) ** (4 * alpha)
        return b * qc * normal / (8 * math.pi * (cos4a + a * qc * qc * np.sin(theta) ** 4) ** ((1 + alpha) / (2 * alpha)))

    def _volume(self, theta: np.ndarray, k: float) -> np.ndarray:
        cos = np.cos(theta)
        im_p = self._p(cos).imag
        t4 = np.abs(1.0 + self._reflection(theta)) ** 4
        with np.errstate(divide="ignore", invalid="ignore"):
            out = 5.0 * self.loss * self.volume_ratio * t4 / (math.log(10.0) * self.density_ratio ** 2 * im_p)
        return np.where(im_p > 0, out, 0.0)


def _grazing(name: str, value) -> np.ndarray:
    theta = v.array(name, value, tuple(-1 for _ in range(np.ndim(value))), copy=False)
    if theta.size and (theta.min() < 0 or theta.max() > np.pi / 2 + 1e-12):
        raise ValueError(f"{name}: grazing angles must be in [0, pi/2] rad, got {theta.min():g} .. {theta.max():g}")
    return np.clip(theta, 0.0, np.pi / 2)


def _frequency(name: str, value) -> float:
    return v.positive(name, value, high=MAX_FREQUENCY, unit="Hz")


#: The handbook's sediments (APL-UW TR 9407, 1994, the bottom-parameter table, rows by mean grain
#: size; rho, nu and delta as tabulated there and reproduced in the open implementation of
#: Jackson's model in HydrOffice OpenBST, w2 in the handbook's cm^4 with gamma2 = 3.25, sigma2
#: 0.002 for sands and coarser, 0.001 for silts and clays). "mud" is the handbook's silt row.
SEDIMENTS = {
    "rock": Sediment("rock", 2.5, 2.5, 0.01374, 3.25, 0.01862, 0.002),
    "gravel": Sediment("gravel", 2.492, 1.337, 0.01705, 3.25, 0.012937, 0.002),
    "coarse_sand": Sediment("coarse_sand", 2.231, 1.2503, 0.01638, 3.25, 0.006957, 0.002),
    "sand": Sediment("sand", 1.845, 1.1782, 0.01624, 3.25, 0.004446, 0.002),
    "fine_sand": Sediment("fine_sand", 1.451, 1.1072, 0.01602, 3.25, 0.002715, 0.002),
    "mud": Sediment("mud", 1.149, 0.9873, 0.00386, 3.25, 0.000518, 0.001),
}
