"""The model floor: the containers that flow between the stages.

:class:`Medium` and :class:`Waveform` (the water and the pulse), :class:`EchoData` (the recorded
cube and its geometry, with the receivers' tracks), :class:`Image` and :class:`Grid`. Nothing
here imports a stage above (scene, synthesis, image, estimate, io): only clsas's ground services.
"""

from .echo import MAX_ECHO_FS, EchoData, ScenarioRecord
from .grid import Grid
from .image import AXIS_UNITS, Image
from .medium import Medium, Waveform

__all__ = ["AXIS_UNITS", "MAX_ECHO_FS", "EchoData", "Grid", "Image", "Medium", "ScenarioRecord", "Waveform"]
