"""The seafloor: its shape (:class:`Seafloor`), its sediment (:class:`Sediment`, the table
:data:`SEDIMENTS`) and its speckle facets (:func:`facets.generate`)."""

from .facets import Facets, facet_spacing, generate
from .floor import Seafloor
from .sediment import LAWS, SEDIMENTS, Sediment

__all__ = ["LAWS", "SEDIMENTS", "Facets", "Seafloor", "Sediment", "facet_spacing", "generate"]
