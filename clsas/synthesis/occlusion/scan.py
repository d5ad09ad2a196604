"""The scan image of a scenario's mesh targets (Kiang & Kiang 2022 section VI, Fig. 9(d))."""

from __future__ import annotations

import numpy as np

from .weights import PathWeights, has_meshes


def scan_image(scenario, r, y, eta: float = 0.0, receiver: int = 0):
    """The scan image of a scenario's mesh targets (Kiang & Kiang 2022 section VI, Fig. 9(d)).

    Every facet that transceiver ``receiver`` (the array's first receiver, A, by default; its
    own transmitter for the outgoing leg) sees lit and unobstructed at slow time ``eta`` is
    projected onto the r-y plane: r its one-way slant range from the receiver, y its along-track
    coordinate (both at the scattering time); its weight (area x angular law, as in the echo
    synthesis) is added into the pixel of the uniform axes ``r`` and ``y`` (m) that contains it.
    Returns an :class:`clsas.model.Image` with dims ("y", "r") and real, non-negative values.
    """
    from ...model import Image
    from ...scene.scenario import PulseSchedule

    r = np.asarray(r, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    for name, ax in (("r", r), ("y", y)):
        if ax.ndim != 1 or ax.size < 2 or not np.all(np.isfinite(ax)) or not np.allclose(np.diff(ax), ax[1] - ax[0]):
            raise ValueError(f"scan_image: {name} must be a uniform, increasing 1-D axis of >= 2 values (m)")
    if not has_meshes(scenario):
        raise ValueError("scan_image: the scenario has no mesh target")
    one = scenario.replace(schedule=PulseSchedule(prf=1.0, n_pulses=1, start=float(eta)))
    path_weights = PathWeights(one)
    weights = path_weights(slice(None))[receiver, 0]  # (n_scatterers,)
    image = np.zeros((y.size, r.size))
    tx = one.receiver_position(receiver, np.array([float(eta)]))[0]
    for first, n, target, _, _ in path_weights.parts:
        if target is None:
            continue
        centres = target.facets_world()[0] + target.velocity * eta
        w = weights[first:first + n] * target.mesh.area_faces
        ri = np.floor((np.linalg.norm(centres - tx, axis=1) - r[0]) / (r[1] - r[0]) + 0.5).astype(int)
        yi = np.floor((centres[:, 1] - y[0]) / (y[1] - y[0]) + 0.5).astype(int)
        keep = (w > 0) & (ri >= 0) & (ri < r.size) & (yi >= 0) & (yi < y.size)
        np.add.at(image, (yi[keep], ri[keep]), w[keep])
    return Image(data=image, dims=("y", "r"), axes={"y": y, "r": r},
                 provenance={"algorithm": "scan_image", "eta": float(eta), "receiver": scenario.receiver_names[receiver]})
