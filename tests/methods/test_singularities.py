"""Singularity clusters: neighbouring discrete singularities merge, indices add up."""

from __future__ import annotations

import numpy as np

from decrun.core.complex import SimplicialComplex
from decrun.methods.singularities import Singularities, cluster_singularities
from decrun.runner.job.config import compose_config
from decrun.runner.job.run import run_experiment

from meshes_for_tests import icosphere


def singularities_at(K, index_by_vertex: dict) -> Singularities:
    v_index = np.zeros(K.num_simplices(0), dtype=np.int64)
    for v, i in index_by_vertex.items():
        v_index[v] = i
    f_index = np.zeros(K.num_simplices(2), dtype=np.int64)
    return Singularities(v_index, f_index, np.flatnonzero(v_index), np.zeros(0, np.int64), int(v_index.sum()),
                         np.ones(K.num_simplices(0), bool), 0.0)


def test_a_plus_plus_minus_cluster_is_one_plus_one_singularity():
    K = SimplicialComplex(*icosphere(3))
    x = K.vertices
    pole = int(np.argmax(x[:, 2]))
    ring = np.flatnonzero(np.isin(np.arange(len(x)), K.simplices(1)[(K.simplices(1) == pole).any(axis=1)].ravel()))
    ring = ring[ring != pole]
    south = int(np.argmin(x[:, 2]))
    found = singularities_at(K, {pole: 1, int(ring[0]): 1, int(ring[2]): -1, south: 1})
    clusters = cluster_singularities(K, found, radius=3 * K.mean_edge_length)
    assert sorted(clusters.indices.tolist()) == [1, 1] and sorted(clusters.sizes.tolist()) == [1, 3]
    assert clusters.summary() == "+1,+1"
    north = clusters.positions[np.argmax(clusters.sizes)]
    assert north[2] > 0.9  # the cluster sits at the pole
    # radius 0: nothing merges, the raw indices come back
    assert sorted(cluster_singularities(K, found, radius=0.0).indices.tolist()) == [-1, 1, 1, 1]


def test_fig6_8_vortex_on_the_clean_sphere_has_two_plus_one_singularities():
    result = run_experiment(compose_config(["+experiment=fig6_8_vortex"])).result
    m = result.metrics
    assert m["singularity_cluster_indices"] == "+1,+1" and m["index_sum"] == 2 == m["euler_characteristic"]
    assert m["singularities"] >= 2  # the raw discrete list may hold +1, +1, −1 triples at the poles
