"""The lagged (Picard) blocks of the semi-implicit step (decrun.methods.model.linear): the
unknown's own operator chain (``d(H)``) is made once and reused at every step, a coefficient
form scales its rows without a sparse product — and at every state the block is the lagged
matrix written out, ⋆0⁻¹ d0ᵀ diag(⋆1 D(H)) d0, with the chain left as it was."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from decrun.core.complex import SimplicialComplex
from decrun.core.dec import DEC
from decrun.methods.model.language import parse_expression
from decrun.methods.model.linear import _rows_scaled
from decrun.methods.model.system import FieldSpec, ModelSpec, compile_model
from decrun.runner.job.plugins import option


@lru_cache(maxsize=None)
def square() -> DEC:
    mesh = option("mesh", "grid", nx=7, ny=7).load()
    return DEC(SimplicialComplex(mesh.vertices, mesh.simplices))


def test_rows_scaled_is_the_diagonal_product_entry_for_entry():
    generator = np.random.default_rng(47)
    A = sp.random(40, 30, density=0.2, random_state=generator, format="csr")
    values = generator.standard_normal(40)
    values[::3] = 0.0  # zero rows: dropped, as the product drops them
    pattern = (A.indptr.copy(), A.indices.copy())
    product = (sp.diags(values) @ A).tocsr()
    scaled = _rows_scaled(A, values)
    product.sort_indices()
    scaled.sort_indices()
    assert scaled.nnz == product.nnz < A.nnz
    np.testing.assert_array_equal(scaled.indices, product.indices)
    np.testing.assert_array_equal(scaled.data, product.data)  # the same products, bit for bit
    np.testing.assert_array_equal(A.indptr, pattern[0])  # A untouched
    np.testing.assert_array_equal(A.indices, pattern[1])


def test_the_lagged_diffusion_block_is_the_matrix_written_out_at_every_state():
    """The same builder at three states (the second with dry edges, the third the first again): each block is d0ᵀ diag(⋆1 c(h)) d0 over ⋆0 (the
    codifferential's weak form) with c = average(H**2) at that state — the cached d(H) block
    is not changed by scaling it."""
    dec = square()
    spec = ModelSpec(fields={"H": FieldSpec(0, "1 + x*y")}, equations=["dt(H) = -codifferential(average(H**2)*d(H))"])
    model = compile_model(spec, dec, None)
    ((sign, term),) = model.compiler.terms(model.equations[0].rhs)
    builder = model.compiler.lagged(term, {"H"})
    coefficient = model.compiler.compile(parse_expression("average(H**2)", "test"), "test")
    d0, star1 = dec.d(0).tocsr(), dec.star(1).diagonal()
    blocks = []
    start = np.asarray(model.initial_values["H"])
    dry = np.maximum(0.0, np.cos(6 * dec.K.vertices[:, 0]))  # c = 0 on some edges: rows dropped
    for h in (start, dry, start):
        env = model.environment({"H": h}, 0.0)
        block = builder(env)["H"]
        c = np.asarray(coefficient(env), dtype=np.float64)
        written = d0.T @ sp.diags(star1 * c) @ d0
        assert sign == -1.0 and block.inv == 0
        assert abs(block.A - written).max() <= 1e-14 * abs(written).max()
        blocks.append(block.A)
    assert abs(blocks[0] - blocks[1]).max() > 0.1 * abs(blocks[0]).max()  # the coefficient moved
    assert (blocks[0] != blocks[2]).nnz == 0  # and back: the same block, bit for bit
