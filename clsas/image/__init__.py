"""EchoData -> Image: range compression and the imaging algorithms."""

from .backprojection import backproject
from .csa import chirp_scaling
from .ffbp import ffbp
from .inclined import correct_inclined_array
from .multireceiver import pca_record
from .ncs import nonlinear_chirp_scaling
from .omegak import omega_k
from .ptrs import ptrs_image
from ..pulse import WINDOWS, lfm_replica, matched_filter, spectral_window
from .rangecomp import range_compress, upsample_records
from .rda import range_doppler
from .stolt import stolt
from .record import LineRecord, line_record

__all__ = ["WINDOWS", "LineRecord", "backproject", "chirp_scaling", "correct_inclined_array", "ffbp", "lfm_replica", "line_record", "matched_filter",
           "nonlinear_chirp_scaling", "omega_k", "pca_record", "ptrs_image", "range_compress", "range_doppler", "spectral_window", "stolt", "upsample_records"]
