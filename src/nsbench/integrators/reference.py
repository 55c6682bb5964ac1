"""``reference``: the most accurate integrator nsbench has for each problem, chosen per problem.

``result.integrator`` names ``reference``; which solver ran is in the module docstring's rule
(linear: ``exact``; cubic: ``heyoka-q``) and in the counters (``exact``'s ``roots`` or heyoka's
``taylor_coefficients``).

Linear problems go to ``exact`` (closed-form flow, guard roots polished in
extended precision); non-linear ones (cubic springs, or a friction law other than
Coulomb's: ``problem.is_linear`` is false) to ``heyoka-q`` at its tightest tolerance (the
real128 epsilon) with compensated summation. Both carry event times in
compensated form between arcs. ``heyoka-q`` also keeps its real128 state and
time across events (a double is produced only for the results), so for cubic
problems no rounding to double enters the trajectory; ``exact`` still rounds
the state to double at each event. Measured accuracy on the 2-DOF runs over
``tau`` in [0, 300], against a 32-digit closed form (tests): within 7e-14 on
cases 1 and 2, where ``exact`` and ``heyoka-q`` also agree with each other to
3e-14; on cases 3 and 4, ``heyoka-ld`` agrees with it to 3e-14. On a sensitive
forced cubic point (case 4 with ``v0=0.323, F=0.755, Omega=0.897, r_f=0.553,
omega_r=5.56``) its event times equal those of an independent real128 solver
rounded to double (tests/integrators/test_heyoka_precision.py), where rounding
the state at events had moved them by 1.2e-11.
"""

from __future__ import annotations

from typing import ClassVar

from nsbench.integrators.base import ArcRequest, ArcResult, Capabilities, Integrator, Option
from nsbench.integrators.exact import ExactIntegrator


class Reference(Integrator):
    """The reference solution: ``exact`` for linear problems, ``heyoka-q`` at its tightest tolerance otherwise."""

    name = "reference"
    capabilities = Capabilities(
        event_location="exact-root or taylor-root",
        order=None,
        adaptive=True,
        needs_jacobian=False,
        supports_nonlinear=True,
        precision="quad",
        step_option=None,
        reference_grade=True,
        checks_steps=True,
    )
    options: ClassVar[dict[str, Option]] = {}

    def setup(self, problem) -> None:
        super().setup(problem)
        if problem.is_linear:
            self.delegate: Integrator = ExactIntegrator()
        else:
            from nsbench.integrators.heyoka_ import HeyokaQuad  # heavy import only when needed

            self.delegate = HeyokaQuad(tol=None, high_accuracy=True)
        if getattr(self, "_checking", False):
            # a check asks the delegate's own refusals, without its compiling or loading
            self.delegate.check_problem(problem)
            return
        self.delegate.setup(problem)
        self._problem = problem

    def sections_refusal(self, problem) -> str:
        if problem.is_linear:
            return ""
        from nsbench.integrators.heyoka_ import HeyokaQuad

        refusal = HeyokaQuad().sections_refusal(problem)
        return f"{self.name} (heyoka-q on this problem): {refusal}" if refusal else ""

    def kernel(self, problem):
        """The delegate's compiled kernel (``exact``'s for linear problems), so the whole run stays compiled."""
        if getattr(self, "_problem", None) is not problem:
            self.setup(problem)
        return self.delegate.kernel(problem)

    def advance(self, request: ArcRequest) -> ArcResult:
        if getattr(self, "_problem", None) is not request.problem:
            self.setup(request.problem)
        return self.delegate.advance(request)
