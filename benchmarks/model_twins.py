"""Every shipped time-dependent model's step written by hand with numpy/scipy — the twins the
model app is measured against (``bench_models.py``, part 1) and checked against
(``tests/apps/test_model_twins.py``: equal to round-off on a small mesh).

Each twin is the scheme of the model's integrator written out on the model's equations with
M = ⋆0 (a vector: it is diagonal) and S = d0ᵀ ⋆1 d0 (the cotan stiffness; Δu = −M⁻¹ S u) built
once, every constant matrix made once, one factorization per run for the linear schemes:

===============  ================  ===================================================================
model            integrator        the hand-written step
===============  ================  ===================================================================
heat             crank_nicolson    (M + dt/2 k S) u⁺ = (M − dt/2 k S) u
                 (implicit_euler)  (M + dt k S) u⁺ = M u
wave             symplectic        v += dt/2 c² Δu;  u += dt v;  v += dt/2 c² Δu  (Störmer–Verlet)
mcf              implicit_euler    (M + dt S) [vx vy vz]⁺ = M [vx vy vz]   (one factor, three columns)
gray_scott       imex              (M + dt (Du S + F M)) u⁺ = M (u + dt (F − u v²)),
                                   (M + dt (Dv S + (F + k) M)) v⁺ = M (v + dt u v²)
brusselator      rk4               f = (Du Δu + A − (B + 1) u + u² v, Dv Δv + B u − u² v), classical RK4
klausmeier       rk4               f = (w n² − m n + Δn − σ (n − n*), a − w − w n² + ν X·∇w − σ (w − w*)),
                                   X·∇w a constant (n0 × n0) matrix (∇ per triangle, averaged to vertices)
cahn_hilliard    imex              (M + dt D (s S + g S M⁻¹ S)) c⁺ = M c − dt D S (c³ − (1 + s) c)
halfar           semi_implicit     (M + dt d0ᵀ ⋆1 diag(D(Hⁿ)) d0) H⁺ = M Hⁿ, D(H) = Γ H̄^{n+2} |∇H|^{n−1}
                                   per triangle averaged onto edges (a new factorization every step)
===============  ================  ===================================================================

:func:`twin` returns ``(step, state)``: ``step()`` advances ``state`` (a dict field → array) by one
step. The constants, ``dt`` and the initial values are the model's (``app.constants``,
``app.dt``, ``model.initial_values``): the twin is the scheme, not the set-up.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["MODELS", "HandSolver", "twin", "mass_and_stiffness"]

#: model → its shipped integrator (the one the twin writes out)
MODELS = {"heat": "crank_nicolson", "wave": "symplectic", "mcf": "implicit_euler", "gray_scott": "imex",
          "brusselator": "rk4", "klausmeier": "rk4", "cahn_hilliard": "imex", "halfar": "semi_implicit"}


class HandSolver:
    """One factorized SPD matrix, solved by SuperLU (``library="direct"``, scipy) or CHOLMOD
    (``"auto"``: the binding ``solver=auto`` uses here — scikit-sparse's supernodal factorization
    where installed, else cholespy — called directly); ``solve(b)`` takes (n,) or (n, k) right sides."""

    def __init__(self, A: sp.spmatrix, library: str):
        from decrun.core.solvers.cholmod import CholmodBackend, installed_backends

        A = sp.csr_matrix(A)
        if library == "direct":
            self.solve = spla.splu(A.tocsc(), permc_spec="COLAMD").solve
        elif installed_backends()[0] is CholmodBackend.sksparse:
            from sksparse.cholmod import cholesky

            self.solve = cholesky(A.tocsc(), mode="supernodal")
        else:
            import cholespy

            A.sort_indices()
            factor = cholespy.CholeskySolverD(A.shape[0], A.indptr.astype(np.int32), A.indices.astype(np.int32),
                                              np.ascontiguousarray(A.data), cholespy.MatrixType.CSR)

            def solve(b):
                b = np.ascontiguousarray(b)
                x = np.empty_like(b)
                factor.solve(b, x)
                return x

            self.solve = solve


def mass_and_stiffness(dec):
    """m = diag ⋆0 (n0,) and S = d0ᵀ ⋆1 d0 (n0, n0) CSR, straight from DEC."""
    m = np.asarray(dec.star(0).diagonal(), dtype=np.float64).copy()
    d0 = dec.d(0)
    S = sp.csr_matrix(d0.T @ dec.star(1) @ d0)
    return m, S


def _rk4(f, state: dict, dt: float) -> dict:
    k1 = f(state)
    k2 = f({u: state[u] + 0.5 * dt * k1[u] for u in state})
    k3 = f({u: state[u] + 0.5 * dt * k2[u] for u in state})
    k4 = f({u: state[u] + dt * k3[u] for u in state})
    return {u: state[u] + dt / 6.0 * (k1[u] + 2 * k2[u] + 2 * k3[u] + k4[u]) for u in state}


def _vertex_average(K) -> sp.csr_matrix:
    """(n0, n2) area-weighted mean over the triangles at each vertex."""
    top = K.simplices(2)
    area = np.repeat(K.top_volumes, 3)
    total = np.bincount(top.ravel(), weights=area, minlength=K.num_simplices(0))
    return sp.csr_matrix((area / total[top.ravel()], (top.ravel(), np.repeat(np.arange(len(top)), 3))),
                         shape=(K.num_simplices(0), len(top)))


def _gradient_matrices(K) -> list[sp.csr_matrix]:
    """[Gx, Gy(, Gz)]: (n2, n0) matrices of the gradient of a piecewise-linear 0-form per triangle."""
    from decrun.core.forms import barycentric_gradients

    top = K.simplices(2)
    grad = barycentric_gradients(K)  # (n2, 3, d)
    rows = np.repeat(np.arange(len(top)), 3)
    return [sp.csr_matrix((grad[:, :, axis].ravel(), (rows, top.ravel())), shape=(len(top), K.num_simplices(0)))
            for axis in range(grad.shape[2])]


def twin(name: str, app, dec, model, library: str = "auto"):
    """``(step, state)``: model ``name``'s step by hand (module docstring) with the constants and
    ``dt`` of ``app`` and the initial values of the compiled ``model``; ``library`` the sparse
    factorization ("direct": SuperLU, "auto": CHOLMOD) — the model's ``solver=`` counterpart."""
    c, dt = dict(app.constants), float(app.dt)
    state = {u: np.array(model.initial_values[u], dtype=np.float64) for u in model.evolved}
    m, S = mass_and_stiffness(dec)
    L = sp.csr_matrix(-(sp.diags(1.0 / m) @ S))  # Δ on 0-forms
    K = dec.K

    if name == "heat":
        k = c["k"]
        if str(app.integrator) == "implicit_euler":  # (M + dt k S) u⁺ = M u
            solve = HandSolver(sp.diags(m) + (dt * k) * S, library).solve

            def step():
                state["u"] = solve(m * state["u"])
        else:
            solve = HandSolver(sp.diags(m) + (0.5 * dt * k) * S, library).solve
            explicit = sp.csr_matrix(sp.diags(m) - (0.5 * dt * k) * S)

            def step():
                state["u"] = solve(explicit @ state["u"])
    elif name == "wave":
        c2 = c["c"] ** 2
        kick = sp.csr_matrix((0.5 * dt * c2) * L)

        def step():
            state["v"] = state["v"] + kick @ state["u"]
            state["u"] = state["u"] + dt * state["v"]
            state["v"] = state["v"] + kick @ state["u"]
    elif name == "mcf":
        solve = HandSolver(sp.diags(m) + dt * S, library).solve
        names = ("vx", "vy", "vz")

        def step():
            out = solve(m[:, None] * np.stack([state[u] for u in names], axis=1))
            for i, u in enumerate(names):
                state[u] = out[:, i]
    elif name == "gray_scott":
        Du, Dv, F, kk = c["Du"], c["Dv"], c["F"], c["k"]
        solve_u = HandSolver(sp.diags((1 + dt * F) * m) + (dt * Du) * S, library).solve
        solve_v = HandSolver(sp.diags((1 + dt * (F + kk)) * m) + (dt * Dv) * S, library).solve

        def step():
            u, v = state["u"], state["v"]
            uvv = u * v * v
            state["u"] = solve_u(m * (u + dt * (F - uvv)))
            state["v"] = solve_v(m * (v + dt * uvv))
    elif name == "brusselator":
        A, B = c["A"], c["B"]
        Lu, Lv = sp.csr_matrix(c["Du"] * L), sp.csr_matrix(c["Dv"] * L)

        def f(s):
            u, v = s["u"], s["v"]
            uuv = u * u * v
            return {"u": Lu @ u + A - (B + 1) * u + uuv, "v": Lv @ v + B * u - uuv}

        def step():
            state.update(_rk4(f, state, dt))
    elif name == "klausmeier":
        a, mm, nu, Ln, r = c["a"], c["m"], c["nu"], c["L"], c["r"]
        x = K.vertices[:, 0]
        ns = (a + np.sqrt(a ** 2 - 4 * mm ** 2)) / (2 * mm)
        sponge = r * ((1 + np.tanh((x - 0.5 * Ln + 50) / 5)) + (1 + np.tanh((-x - 0.5 * Ln + 50) / 5))) / 2
        gradients = _gradient_matrices(K)
        X = [G @ x for G in gradients]  # ∇x per triangle (sharp(d(x)) is exact on linear functions)
        advect = sp.csr_matrix(_vertex_average(K) @ sum(sp.diags(Xa) @ G for Xa, G in zip(X, gradients, strict=True)))
        advect_nu = sp.csr_matrix(nu * advect)
        n_target, w_target = sponge * ns, sponge * (mm / ns)

        def f(s):
            n, w = s["n"], s["w"]
            wnn = w * n * n
            return {"n": wnn - mm * n + L @ n - sponge * n + n_target,
                    "w": a - w - wnn + advect_nu @ w - sponge * w + w_target}

        def step():
            state.update(_rk4(f, state, dt))
    elif name == "cahn_hilliard":
        D, g, s_ = c["D"], c["g"], c["s"]
        solve = HandSolver(sp.diags(m) + (dt * D) * (s_ * S + g * (S @ sp.diags(1.0 / m) @ S)), library).solve
        DS = sp.csr_matrix((dt * D) * S)

        def step():
            cc = state["c"]
            state["c"] = solve(m * cc - DS @ (cc ** 3 - (1 + s_) * cc))
    elif name == "halfar":
        n_, A_, rho, g = c["n"], c["A"], c["rho"], c["g"]
        gamma = 2 * A_ * (rho * g) ** n_ / (n_ + 2)
        top = K.simplices(2)
        gradients = _gradient_matrices(K)
        table = K.top_face_indices(1)  # the three edges of each triangle
        count = np.bincount(table.ravel(), minlength=K.num_simplices(1)).astype(np.float64)
        to_edges = sp.csr_matrix((1.0 / count[table.ravel()], (table.ravel(), np.repeat(np.arange(len(top)), 3))),
                                 shape=(K.num_simplices(1), len(top)))
        d0 = sp.csr_matrix(dec.d(0))
        star1 = np.asarray(dec.star(1).diagonal(), dtype=np.float64)
        M = sp.diags(m)
        counter = {"factorizations": 0}

        def step():
            H = state["H"]
            grad2 = sum((G @ H) ** 2 for G in gradients)
            mean = H[top].mean(axis=1)
            D = to_edges @ (gamma * mean ** (n_ + 2) * grad2 ** ((n_ - 1) / 2))
            A = M + dt * (d0.T @ sp.diags(star1 * D) @ d0)
            state["H"] = HandSolver(A, library).solve(m * H)
            counter["factorizations"] += 1
    else:
        raise ValueError(f"no hand-written twin of model {name!r}; there are {sorted(MODELS)}")
    return step, state


def model_and_twin(name: str, overrides: list[str], library: str = "auto"):
    """``(model_step, stepper, hand_step, hand_state)`` for ``decrun app=<name> <overrides>``:
    the compiled model's step as ``run_steps`` calls it
    (:class:`~decrun.methods.model.stepper.ModelStepper`, ``solver=<library>``) and its
    hand-written twin, both from the same initial state."""
    from decrun.core.solvers import solver_factory
    from decrun.methods.model.integrators import make_integrator
    from decrun.methods.model.stepper import ModelStepper
    from decrun.runner.job.config import compose_config
    from decrun.runner.job.run import prepare

    run = prepare(compose_config([f"app={name}", f"solver={library}", "figures=false", "progress=false",
                                  "app.stability_check=false", *overrides]))
    app, dec = run.experiment.app, run.dec
    if str(app.integrator) != MODELS[name] and not (name == "heat" and str(app.integrator) == "implicit_euler"):
        raise ValueError(f"the twin of {name} is its {MODELS[name]} step, not app.integrator={app.integrator}")
    new_solver = solver_factory(library)
    model = app.compiled(dec, new_solver)
    stepper = ModelStepper(model, make_integrator(model, str(app.integrator), app.dt, new_solver), app.dt)
    counter = {"n": 0}

    def model_step():
        counter["n"] += 1
        error = stepper.step(counter["n"])
        if error:
            raise FloatingPointError(error)

    hand_step, hand_state = twin(name, app, dec, model, library)
    return model_step, stepper, hand_step, hand_state
