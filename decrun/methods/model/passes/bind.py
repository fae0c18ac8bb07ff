"""The bind pass: a model's values on the mesh — the built-in names (coordinates, h, π, t, dt),
the constants, the sampled initial values of the evolved fields and inputs, and each field's
Dirichlet values on the border simplices."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from decrun.methods.model import borders
from decrun.methods.model.initial import sample
from decrun.methods.model.kinds import Kind
from decrun.methods.model.language import ModelError
from decrun.methods.model.operators import Discrete

if TYPE_CHECKING:
    from decrun.methods.model.system import ModelSpec

__all__ = ["border_simplices"]


def border_simplices(K, k: int) -> np.ndarray:
    """(b,) indices of the k-simplices (k < n) on the border: the faces of border (n−1)-simplices."""
    from itertools import combinations

    n = K.dim
    border = K.border_faces()[0]
    if k >= n or border.size == 0:
        return np.zeros(0, dtype=np.int64)
    facets = K.simplices(n - 1)[border]
    if k == n - 1:
        return np.sort(border)
    tuples = np.concatenate([facets[:, list(c)] for c in combinations(range(n), k + 1)])
    return np.unique(K.find_simplices(np.unique(tuples, axis=0)))


def _bind_values(spec: ModelSpec, ops: Discrete, kinds: dict[str, Kind], evolved: list[str], inputs: list[str],
                 chained: dict | None) -> tuple[dict, dict]:
    """The bind pass: the built-in names' values on the mesh (coordinates, h, π, t, dt), the
    constants and the inputs — ``base``, what every evaluation starts from — and the sampled
    initial values of the evolved fields and inputs."""
    dec, K = ops.dec, ops.K
    base = {"x": K.vertices[:, 0].copy(), "y": K.vertices[:, 1].copy() if K.embedding_dim > 1 else
            np.zeros(K.num_simplices(0)), "z": K.vertices[:, 2].copy() if K.embedding_dim > 2 else
            np.zeros(K.num_simplices(0)), "h": ops.mean_edge_length(), "pi": float(np.pi), "t": 0.0,
            "area": float(K.top_volumes.sum()),  # a field or constant named area takes its place
            "dt": float(spec.dt)}
    base.update({name: float(value) for name, value in spec.constants.items()})
    initial_values = {}
    for name in evolved + inputs:
        initial_values[name] = sample(spec.fields[name].initial, kinds[name], dec, f"{spec.key}.fields.{name}.initial",
                                      constants=spec.constants, seed=spec.seed, name=name, chained=chained)
    base.update({name: initial_values[name] for name in inputs})
    return base, initial_values


def _dirichlet(spec: ModelSpec, kinds: dict[str, Kind], dec, key: str) -> dict:
    fixed = {}
    K = dec.K
    for name, field_spec in spec.fields.items():
        if field_spec.dirichlet is None:
            continue
        where = f"{key}.fields.{name}.dirichlet"
        kind = kinds[name]
        if kind.dual or kind.degree >= K.dim:
            raise ModelError(f"{where}: border values fix primal forms of degree < {K.dim} on the border simplices; "
                             f"{name} is a {kind}")
        border = border_simplices(K, kind.degree)
        if border.size == 0:
            raise ModelError(f"{where}: this mesh has no border (a closed surface); drop the condition with "
                             f"`{key}.fields.{name}.dirichlet=null`")
        values = borders.dirichlet_at_start(spec, name, kind, dec, where)
        if values is None:
            values = sample(field_spec.dirichlet, kind, dec, where, constants=spec.constants, seed=spec.seed, name=name)
        fixed[name] = (border, values[border])
    return fixed
