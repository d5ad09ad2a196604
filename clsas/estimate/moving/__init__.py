"""Moving-target estimation and focusing (Kiang & Kiang 2022, sections III-VII).

- :func:`closed_forms`: the true K_a,eq, f_dc,eq, tau_c, eta_c of a point target at every receiver
  (eqs. 3-6, 15-16, 23-25, 28, 32-35; exact non-stop-and-go Taylor coefficients);
- :func:`solve_velocity` / :func:`solve_motion`: the velocity vector (section V), and the
  position with it when it is not known.
"""

from .closedforms import Predicted, closed_forms
from .doppler import Doppler
from .layout import Layout, layout_of
from .velocity import MotionSolution, solve_motion, solve_velocity

__all__ = ["Doppler", "Layout", "MotionSolution", "Predicted", "closed_forms", "layout_of", "solve_motion",
           "solve_velocity"]
