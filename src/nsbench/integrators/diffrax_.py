"""``diffrax-*``: diffrax (JAX) per mode, the guards as one ``diffrax.Event`` located by bisection.

diffrax (Patrick Kidger; PyPI ``diffrax``, on JAX, installed by the extra ``[jax]``) solves
each arc of a frozen mode with an explicit Runge-Kutta method (``diffrax-tsit5``: Tsitouras
5(4), diffrax's recommended default; ``diffrax-dopri8``: Dormand-Prince 8(7), for tight
tolerances) under its PID step-size controller, and ends the arc with a ``diffrax.Event``:
one real condition, the smallest ``expected_sign * guard`` over the mode's guards (positive
until the earliest crossing of any of them), crossing downwards (``direction=False``), its
root located on the step's dense interpolant by optimistix's bisection to two doubles
(:func:`_bracketing`, :data:`ROOT_RTOL`); the guard that fired is the smallest there.

**What it runs: the piecewise-linear problems.** JAX traces the vector field, so nsbench's
numba-compiled law cannot be used; every mode of a piecewise-linear problem is
``y' = A y + b0 + bc cos(w t) + bs sin(w t)`` and every guard a row ``q . [y, 1, cos w t,
sin w t]`` (``HybridProblem.linear_form``, ``guard_row``), and one JAX function of those
arrays serves every mode and every such problem. So it runs the friction family with
linear springs and Coulomb's law (``one-dof``, ``two-dof``, ``chain`` cases 1 and 2,
``block-on-ground``), ``bouncing-ball``, ``impact-oscillator`` and ``relay-feedback``; it
refuses at setup, with the reason, cubic springs (cases 3, 4), the weakening and Stribeck
laws and ``henon-heiles`` (not piecewise linear). It records no state sections (diffrax's
events end the solve), so a sweep's ``peaks`` refuses it.

**Compilation, once per shape.** The solve is ``jax.jit``-compiled once per (method, number
of states, number of guards): the arrays of the mode, the tolerances and the times are
arguments, not constants, so every mode, accuracy level and problem of one shape reuses the
compiled code. :meth:`DiffraxIntegrator.setup` compiles it (one short arc from the problem's
start, about 20 s per shape on the 2-core machine), so the bench counts the compilation in
``setup`` and times warm runs. An arc runs in chunks of at most :data:`CHUNK` steps and
:data:`N_EVAL` output times (JAX needs static sizes; a chunk restarts the solver at its end);
a step budget below a chunk compiles once more for a smaller chunk (the end of a run that
exhausts its budget). JAX runs in double precision (``jax_enable_x64``, set on first use).

``nfev`` is computed from the method's tableau (diffrax counts steps, not evaluations):
stages per attempted step, less one for the first-same-as-last stage of accepted steps,
plus the two evaluations of the initial step selection per chunk.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from nsbench.errors import UnsupportedProblemError
from nsbench.integrators._optional import OptionalBackend
from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Option
from nsbench.status import Status

#: Most steps of one compiled solve (a chunk of an arc); an arc takes as many chunks as it needs.
CHUNK = 4096
#: Most output times (``t_eval``) of one chunk; an arc with more ends a chunk at the last one.
N_EVAL = 512
#: Relative width of the bracket on the event time where the root finder stops (4 eps: two doubles).
ROOT_RTOL = 4.0 * 2.0**-52

#: Compiled solves by (method, n_states, n_guards, chunk): built once per process.
_COMPILED: dict[tuple[str, int, int, int], Any] = {}


@dataclass(frozen=True)
class _Method:
    """A diffrax solver and its cost per step (for ``nfev``)."""

    solver: str  # the diffrax class name
    stages: int  # right-hand sides per attempted step
    fsal: bool  # first same as last: an accepted step saves one


METHODS = {
    "tsit5": _Method("Tsit5", 7, True),
    "dopri8": _Method("Dopri8", 14, False),
}


def _jax():
    """Import JAX in double precision (x64 must be set before the first array), with a compilation cache on disk.

    The cache (``NSBENCH_JAX_CACHE``, default ``~/.cache/nsbench/jax``; unless the user set JAX's own)
    keeps XLA's compiled code between processes, so a bench worker's setup traces the solve but
    compiles less.
    """
    import os

    import jax

    jax.config.update("jax_enable_x64", True)
    if jax.config.jax_compilation_cache_dir is None:
        default = os.path.join(os.path.expanduser("~"), ".cache", "nsbench", "jax")
        jax.config.update("jax_compilation_cache_dir", os.environ.get("NSBENCH_JAX_CACHE", default))
    return jax


def _build(method: str, n: int, n_guards: int, chunk: int):
    """The jitted solve of one chunk for this shape (see the module docstring)."""
    jax = _jax()
    import diffrax
    import jax.numpy as jnp

    _Bracketing = _bracketing()
    solver = getattr(diffrax, METHODS[method].solver)()

    def field(t, y, args):
        a, b0, bc, bs, w = args["A"], args["b0"], args["bc"], args["bs"], args["w"]
        return a @ y + b0 + bc * jnp.cos(w * t) + bs * jnp.sin(w * t)

    def values(t, y, args):
        """``expected_sign * guard`` of every guard (a row per guard, padding included)."""
        w, t0 = args["w"], args["t0"]
        z = jnp.concatenate([y, jnp.stack([jnp.ones(()), jnp.cos(w * t), jnp.sin(w * t)])])
        value = args["S"] * (args["Q"] @ z)
        # a guard that starts on its own surface: divided by t - t0 (its rate at t0 itself), the same crossings
        # after t0 and none at t0
        at_start = t == t0
        divided = jnp.where(at_start, args["rate"], value / jnp.where(at_start, 1.0, t - t0))
        value = jnp.where(args["on"], divided, value)
        return value + jnp.where(value == 0.0, 1e-300, 0.0)  # an exact zero is on the surface, not across it

    def cond(t, y, args, **kwargs):
        # the smallest: positive while no guard has crossed, so its first zero is the earliest crossing of any
        # guard (several conditions would be located in the order of their list, not of their times)
        return jnp.min(values(t, y, args))

    event = diffrax.Event(cond, root_finder=_Bracketing(rtol=ROOT_RTOL, atol=0.0, flip=True), direction=False)

    def solve(y0, t0, t1, ts, args, rtol, atol, dtmax):
        controller = diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax)
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(field),
            solver,
            t0,
            t1,
            None,
            y0,
            args={**args, "t0": t0},  # the chunk's start: a guard on its surface is divided there
            saveat=diffrax.SaveAt(ts=ts, t1=True),
            stepsize_controller=controller,
            event=event,
            max_steps=chunk,
            throw=False,
            adjoint=diffrax.ForwardMode(),
        )
        return (
            sol.ts,
            sol.ys,
            getattr(sol.result, "_value"),  # the code's integer (diffrax's RESULTS item wraps it)
            sol.stats["num_accepted_steps"],
            sol.stats["num_rejected_steps"],
        )

    return jax.jit(solve)


def _bracketing():
    """optimistix's bisection, stopped by the width of its bracket alone.

    diffrax starts its root finder at the end of the step, with the step as the bracket. Newton's
    method (optimistix's) leaves the bracket where the interpolant's slope at the step's end has the
    other sign (it stopped, clipped to the end, on 2-DOF case 2 with Dopri8) and cannot end where its
    iterates circle between neighbouring doubles; bisection keeps the bracket. optimistix's own test
    also asks ``|guard| < atol``, which a guard of slope above 1 never meets at rounding: this one
    stops when the bracket is within ``rtol |t|`` (two doubles at :data:`ROOT_RTOL`), about 50 halvings
    of a step, each an evaluation of the interpolant.
    """
    import jax.numpy as jnp
    import optimistix as optx

    class Bracketing(optx.Bisection):
        def terminate(self, fn, y, args, options, state, tags):
            width = jnp.abs(state.lower - state.upper)
            return width <= self.atol + self.rtol * jnp.abs(y), optx.RESULTS.successful

    return Bracketing


def compiled(method: str, n: int, n_guards: int, chunk: int = CHUNK):
    """The compiled solve for this shape, built on first use and kept for the process."""
    key = (method, n, n_guards, chunk)
    if key not in _COMPILED:
        _COMPILED[key] = _build(method, n, n_guards, chunk)
    return _COMPILED[key]


def _result_codes() -> tuple[int, int, int]:
    """diffrax's result codes: success, max steps reached, event occurred."""
    import diffrax

    r = diffrax.RESULTS
    names = ("successful", "max_steps_reached", "event_occurred")
    ok, most, event = (int(getattr(getattr(r, name), "_value")) for name in names)
    return ok, most, event


class DiffraxIntegrator(OptionalBackend):
    """Base of the diffrax adapters; subclasses set ``method`` (a key of :data:`METHODS`)."""

    ecosystem = "JAX (diffrax)"
    backend_modules = ("jax", "diffrax", "optimistix")
    extra = "jax"
    method: ClassVar[str] = ""
    options = {
        "rtol": Option(1e-8, float, lower=0.0, upper=1.0, doc="relative tolerance"),
        "atol": Option(1e-10, float, lower=0.0, doc="absolute tolerance"),
        "max_step": Option(
            None,
            float,
            lower=0.0,
            nullable=True,
            unbounded=True,
            doc="largest step (time units); None: 1/16 of the forcing period if forced; inf: no limit",
        ),
    }
    accuracy_levels = tuple({"rtol": r, "atol": r * 1e-2} for r in (1e-6, 1e-9, 1e-12))

    def setup(self, problem) -> None:
        super().setup(problem)  # refuses a problem that is not piecewise linear (supports_nonlinear=False)
        try:
            problem.linear_form(problem.initial_mode(0.0, problem.initial_state()))
        except ValueError as exc:
            raise UnsupportedProblemError(f"{self.name}: {exc}") from None
        if getattr(self, "_checking", False):
            return
        # compile (or load) the solve of this shape: one short arc from the start, untimed
        y0 = problem.initial_state()
        mode = problem.initial_mode(0.0, y0)
        self.advance(ArcRequest(problem, mode, 0.0, y0, 1e-3, problem.guards(mode)))

    def check_problem(self, problem) -> None:
        """The refusals of :meth:`setup`, without compiling."""
        self._checking = True
        try:
            self.setup(problem)
        finally:
            self._checking = False

    def sections_refusal(self, problem) -> str:
        return f"{self.name} records no state sections: diffrax's events end the solve"

    @staticmethod
    def _arrays(problem, mode, guards, t0: float, y0: np.ndarray) -> tuple[dict[str, np.ndarray], int]:
        """The mode's linear form and its guards as the compiled solve's arguments, padded to the problem's guards."""
        a, b0, bc, bs = problem.linear_form(mode)
        n = problem.n_states
        n_guards = max(problem.max_guards, 1)
        q = np.zeros((n_guards, n + 3))
        q[:, n] = 1.0  # padding: the constant 1, never crossed
        s = np.ones(n_guards)
        on = np.zeros(n_guards, bool)
        rate, curve = np.zeros(n_guards), np.zeros(n_guards)
        w = float(problem.forcing_frequency)
        t0 = float(t0)
        y0 = np.asarray(y0, dtype=float)
        c, sn = math.cos(w * t0), math.sin(w * t0)
        z0 = np.concatenate([y0, [1.0, c, sn]])
        dy = a @ y0 + b0 + bc * c + bs * sn
        dz0 = np.concatenate([dy, [0.0, -w * sn, w * c]])
        ddz0 = np.concatenate([a @ dy - w * bc * sn + w * bs * c, [0.0, -w * w * c, -w * w * sn]])
        for k, g in enumerate(guards):
            q[k] = problem.guard_row(mode, g.code, g.block - 1)
            s[k] = float(g.expected_sign)
            if float(q[k] @ z0) == 0.0:
                on[k] = True
                rate[k], curve[k] = s[k] * float(q[k] @ dz0), 0.5 * s[k] * float(q[k] @ ddz0)
        args = {
            "A": a,
            "b0": b0,
            "bc": bc,
            "bs": bs,
            "w": np.float64(w),
            "Q": q,
            "S": s,
            "on": on,
            "rate": rate,
            "curve": curve,
        }
        return args, n_guards

    def advance(self, request: ArcRequest) -> ArcResult:
        problem = request.problem
        y0 = np.array(request.y0, dtype=float)
        if request.sections:
            return ArcResult(
                t=float(request.t0),
                y=y0,
                fired=None,
                y_eval=np.empty((problem.n_states, 0)),
                status=Status.INTEGRATOR_FAILURE,
                message=self.sections_refusal(problem),
            )
        return self._run(request)

    def _run(self, request: ArcRequest) -> ArcResult:
        """The arc, chunk by chunk (see the module docstring)."""
        problem = request.problem
        n = problem.n_states
        args, n_guards = self._arrays(problem, request.mode, request.guards, request.t0, request.y0)
        start_on = args["on"].copy()
        spec = METHODS[self.method]
        opts = self.settings
        max_step = opts["max_step"]
        if max_step is None:
            w = problem.forcing_frequency
            max_step = (2.0 * np.pi / w) / 16.0 if (problem.is_forced and w > 0.0) else np.inf
        ok, max_steps_code, event_code = _result_codes()
        t_eval = np.asarray(request.t_eval, dtype=float)
        t, y, t_end = float(request.t0), np.array(request.y0, dtype=float), float(request.t_end)
        taken = rejected = chunks = 0
        out_eval: list[np.ndarray] = []
        n_done = 0  # t_eval points already returned
        fired, status, message = None, Status.SUCCESS, ""
        while True:
            budget = int(request.max_steps) - taken
            if budget <= 0:
                status, message = Status.BUDGET_EXHAUSTED, f"step budget exhausted at t = {t:.6g}"
                break
            # a budget below a chunk: the largest power of 16 within it (a few more compilations, near its end)
            chunk = CHUNK if budget >= CHUNK else 16 ** int(math.log(budget, 16) + 1e-12)
            # times at or before the start: the core asks for them after a jump in time (the limit of a Zeno
            # accumulation, which it applied at once): the state it gave there
            before = int(np.searchsorted(t_eval, t, side="right")) - n_done
            if before > 0:
                out_eval.append(np.repeat(y.reshape(-1, 1), before, axis=1))
                n_done += before
            pending = t_eval[n_done:][t_eval[n_done:] <= t_end]
            t1 = t_end if pending.size <= N_EVAL else float(pending[N_EVAL - 1])
            wanted = pending[pending <= t1][:N_EVAL]
            ts = np.full(N_EVAL, t1)
            ts[: wanted.size] = wanted
            solve = compiled(self.method, n, n_guards, chunk)
            ts_out, ys_out, code, acc, rej = solve(
                y, np.float64(t), np.float64(t1), ts, args, opts["rtol"], opts["atol"], np.float64(max_step)
            )
            chunks += 1
            taken, rejected = taken + int(acc), rejected + int(rej)
            ts_out, ys_out, code = np.asarray(ts_out), np.asarray(ys_out), int(code)
            # the saved times are packed: the wanted ones up to the chunk's end, then its end (the event),
            # then inf where an event cut the chunk short
            last = int(np.count_nonzero(np.isfinite(ts_out))) - 1
            t_new, y_new = float(ts_out[last]), np.array(ys_out[last], dtype=float)
            got = min(last, wanted.size)
            if got:
                out_eval.append(np.array(ys_out[:got], dtype=float).T)
                n_done += got
            t, y = t_new, y_new
            if code == event_code:
                fired = self._fired(problem, args, request, t, y, start_on if chunks == 1 else None)
                break
            if code not in (ok, max_steps_code):
                status, message = Status.INTEGRATOR_FAILURE, f"diffrax result code {code} after t = {t:.6g}"
                break
            if t >= t_end:
                break
            # the next chunk starts off every surface (a guard is on one only at the arc's start)
            args["on"] = np.zeros_like(args["on"])
        nfev = taken * (spec.stages - (1 if spec.fsal else 0)) + rejected * spec.stages + 2 * chunks
        y_eval = np.concatenate(out_eval, axis=1) if out_eval else np.empty((n, 0))
        y_eval = y_eval[:, : int(np.searchsorted(t_eval, t, side="right"))]
        return ArcResult(
            t=t,
            y=y,
            fired=fired,
            y_eval=y_eval,
            nfev=int(nfev),
            nsteps=taken,
            extra={"rejected_steps": float(rejected), "chunks": float(chunks)},
            status=status,
            message=message,
        )

    @staticmethod
    def _fired(problem, args, request: ArcRequest, t: float, y: np.ndarray, on: np.ndarray | None) -> int | None:
        """The guard at the event: the smallest ``expected_sign * guard`` there (the one the root finder's
        minimum followed to zero); on an exact tie the lowest index (``argmin`` takes the first)."""
        if not request.guards:
            return None
        w = float(problem.forcing_frequency)
        z = np.concatenate([y, [1.0, math.cos(w * t), math.sin(w * t)]])
        k = len(request.guards)
        values = args["S"][:k] * (args["Q"][:k] @ z)
        if on is not None and t != float(request.t0):  # divided as in the compiled condition
            values = np.where(on[:k], values / (t - float(request.t0)), values)
        return int(np.argmin(values))


def _caps(order: int) -> Capabilities:
    return Capabilities(
        event_location="newton-root",
        order=order,
        adaptive=True,
        supports_nonlinear=False,
        precision="double",
        step_option="rtol",
    )


class DiffraxTsit5(DiffraxIntegrator):
    """diffrax's Tsitouras 5(4) (JAX, jit-compiled once per shape), guards as one Event located by bisection."""

    name = "diffrax-tsit5"
    method = "tsit5"
    capabilities = _caps(5)


class DiffraxDopri8(DiffraxIntegrator):
    """diffrax's Dormand-Prince 8(7) (JAX, jit-compiled once per shape), guards as one Event located by bisection."""

    name = "diffrax-dopri8"
    method = "dopri8"
    capabilities = _caps(8)
