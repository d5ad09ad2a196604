"""Moving-target estimation and focusing (Kiang & Kiang 2022, sections III-VII).

- :func:`estimate` (``clsas.estimate_motion``): velocity (and position) of a moving target from a
  raw echo of >= 3 receivers; :func:`focus` (``clsas.focus_moving``): its images on the r-y plane;
- :func:`closed_forms`: the true K_a,eq, f_dc,eq, tau_c, eta_c of a point target at every receiver
  (eqs. 3-6, 15-16, 23-25, 28, 32-35; exact non-stop-and-go Taylor coefficients);
- :func:`solve_velocity` / :func:`solve_motion`: the velocity vector (section V), and the
  position with it when it is not known;
- :func:`estimate_receiver` / :func:`focus_receiver` (:mod:`.chain`): one receiver's chain
  (RFRT, modified SoWVD, RCMC, Radon, RWC, azimuth compression; sections III-IV), also step by
  step (``records.records``, ``sowvd``, :mod:`.centroid`'s ``rcmc`` and
  ``doppler_centroid_radon``, :mod:`.azimuth`'s ``focus_bins``, :mod:`.located`'s ``locate``); :mod:`.extent`: where an extended target's centre lies in its focused image;
- :func:`delay_history` / :func:`higher_order_delay`: the exact delay of the model over the
  aperture, and its terms beyond the quadratic that the chain's focus leaves;
- :mod:`.sharpen`: the residual phase of a focused target by image sharpness (what the velocity
  error leaves over 80 s apertures);
- :mod:`.mapping`: tau-eta -> r-y (section VI) and SSIM against a reference image;
  :mod:`.compare`: RDA, CSA and omega-k run stop-and-go with the estimated velocity (VII-A).
"""

from .chain import ReceiverEstimate, estimate_receiver
from .receiver_focus import focus_receiver
from .closedforms import Predicted, closed_forms, delay_history, higher_order_delay
from .doppler import Doppler
from .extent import Extent
from .layout import Layout, layout_of
from .focus import focus, ry_grid
from .motion import MotionEstimate, estimate, motion_from_receivers
from .targets import estimate_motions
from .velocity import MotionSolution, solve_motion, solve_velocity

__all__ = ["Doppler", "Extent", "Layout", "MotionEstimate", "MotionSolution", "Predicted", "ReceiverEstimate",
           "closed_forms", "delay_history", "estimate", "estimate_motions", "estimate_receiver", "focus", "focus_receiver",
           "higher_order_delay", "layout_of", "motion_from_receivers", "ry_grid", "solve_motion", "solve_velocity"]
