"""Hull occlusion of scattered paths by ray casting (Embree through embreex), with a brute-force
Moller-Trumbore reference, and the per-path weights of mesh targets.

For every pulse and facet of a :class:`clsas.scene.targets.MeshTarget`: the facet is lit when
it faces the transmitter (at its emission position) and the segment from the facet to the
transmitter is free of the hull; it is heard by receiver h when it faces the receiver (at its
reception position) and that segment is free too (Kiang & Kiang 2022, section VI and Fig. 17:
the hull blocks scattered waves). The target moves: the rays are cast in its body frame at the
facet's scattering time (eta + t1 of :mod:`clsas.geometry`), where the hull is fixed.
Back-facing facets are dark without casting a ray. A path's weight is
lit x heard x the target's angular law (:meth:`MeshTarget.angular_gain`).

Rays start a small distance (1e-5 of the hull's size) off the facet along its normal, so that
a facet does not shadow itself; rays end at the transmitter / receiver. Outgoing and incoming
legs are solved in closed form when the motion is uniform (:func:`geometry.meet_time`).

Visibility changes slowly from pulse to pulse (at 2 km a 3 m/s platform turns the direction
from a facet by ~2e-5 rad per pulse at 80 Hz), so a facet's state is reused between two cast
pulses when both casts agree and the directions differ by at most a stated angle
(:class:`PathWeights` ``reuse_tolerance``); where they disagree the pulses between are bisected
down to the pulse where the state changes. The facing test and the angular law are computed
for every path.
"""

from __future__ import annotations

from .rays import DEFAULT_REUSE_TOLERANCE, METHODS, RayCaster, occluded_reference, visibility
from .scan import scan_image
from .weights import PathWeights, has_meshes, needs_path_weights, scene_scatterers

__all__ = ["DEFAULT_REUSE_TOLERANCE", "METHODS", "PathWeights", "RayCaster", "has_meshes", "needs_path_weights",
           "occluded_reference", "scan_image", "scene_scatterers", "visibility"]
