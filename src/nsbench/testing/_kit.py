"""Running the checks: on one integrator (:func:`check_integrator`) or as pytest items.

:func:`parametrize_with_checks` turns every (integrator, check) pair into its own pytest item.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

from nsbench.errors import ConfigError, UnsupportedProblemError
from nsbench.integrators.base import Integrator
from nsbench.testing._checks import (
    CHECKS,
    ONE_CONFIGURATION,
    STEPPED,
    Check,
    CheckSkipped,
    checking_on,
    checking_with,
    configured,
    given_options,
    on_presets,
    problem_family,
    step_levels,
)

PASSED, FAILED, SKIPPED, XFAIL, XPASS = "passed", "failed", "skipped", "xfail", "xpass"


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check on one integrator.

    ``status`` is ``'passed'``, ``'failed'``, ``'skipped'`` (does not apply to
    the integrator's capabilities), ``'xfail'`` (a declared known gap that
    fails) or ``'xpass'`` (a declared known gap that passes); ``message`` says why.
    """

    integrator: str
    check: str
    status: str
    message: str
    seconds: float
    #: The check runs the integrator on the problem (see :attr:`Check.runs`).
    runs: bool = True

    @property
    def ok(self) -> bool:
        return self.status != FAILED


def as_integrator(obj: Any) -> Integrator:
    """An integrator from a registry name, an :class:`Integrator` subclass or an instance."""
    if isinstance(obj, Integrator):
        return obj
    if isinstance(obj, type) and issubclass(obj, Integrator):
        return obj()
    if isinstance(obj, str):
        from nsbench.integrators import get_integrator

        return get_integrator(obj)
    raise ConfigError(f"expected an integrator name, class or instance, got {obj!r}")


def known_gaps(integ: Integrator) -> dict[str, str]:
    """The checks an integrator declares it does not pass, with the reason."""
    gaps = dict(getattr(type(integ), "known_gaps", {}) or {})
    unknown = set(gaps) - {c.name for c in CHECKS}
    if unknown:
        raise ConfigError(f"{type(integ).name}: known_gaps names unknown checks {sorted(unknown)}")
    return gaps


def checks_for(integ: Integrator, only: Sequence[str] | None = None) -> list[Check]:
    """The checks to run, all of them or the named ones."""
    if only is None:
        return list(CHECKS)
    names = {c.name: c for c in CHECKS}
    missing = [n for n in only if n not in names]
    if missing:
        raise ConfigError(f"unknown checks {missing}; available: {', '.join(names)}")
    return [names[n] for n in only]


def configure(obj: Any, options: dict[str, Any] | None = None) -> tuple[Integrator, dict[str, Any]]:
    """The integrator to check and the options the user chose for it.

    ``obj`` as for :func:`as_integrator`; ``options`` are set on top of it. The
    chosen options are ``options`` and the settings of a configured instance that
    differ from the defaults: every check runs with them (see :func:`plan`).
    """
    integ = as_integrator(obj)
    given = given_options(integ, options)
    if options:
        integ = type(integ)(**{**integ.settings, **given})
    return integ, given


def plan(
    obj: Any,
    options: dict[str, Any] | None = None,
    checks: Sequence[str] | None = None,
    problem: str | dict[str, Any] | None = None,
) -> list[str]:
    """What the accuracy checks will run, one line each: the configuration of the single-configuration
    checks and the levels of the stepped ones (of ``checks``, default all, that apply to the integrator
    on ``problem``)."""
    integ, given = configure(obj, options)
    caps = type(integ).capabilities
    lines = []
    with checking_on(problem), checking_with(given):
        applies = {c.name for c in checks_for(integ, checks) if c.skip_reason(caps) is None}
        one = [n for n in ONE_CONFIGURATION if n in applies]
        if one:
            lines.append(f"{', '.join(one)} at {configured(integ)[1]}")
        stepped = [n for n in STEPPED if n in applies]
        if stepped:
            lines.append(f"{', '.join(stepped)} at {step_levels(integ)[1]}")
    return lines


def run_check(
    integ: Integrator, check: Check, problem: str | dict[str, Any] | None = None, options: dict[str, Any] | None = None
) -> CheckResult:
    """Run one check on a fresh copy of ``integ`` and classify the outcome.

    ``problem`` is the problem family of the checks (default the 2-DOF
    oscillator; see :func:`nsbench.testing.checking_on`); ``options`` are set on
    the integrator and used by the check, as for :func:`check_integrator`.
    """
    integ, given = configure(integ, options)
    with checking_on(problem), checking_with(given):
        return _run_check(integ, check)


def _run_check(integ: Integrator, check: Check) -> CheckResult:
    cls = type(integ)
    reason = check.skip_reason(cls.capabilities)
    if reason is not None:
        return CheckResult(cls.name, check.name, SKIPPED, reason, 0.0, runs=check.runs)
    gap = known_gaps(integ).get(check.name)
    tic = time.perf_counter()
    try:
        check.run(cls.from_config(integ.config()))
    except CheckSkipped as exc:
        return CheckResult(cls.name, check.name, SKIPPED, str(exc), time.perf_counter() - tic, runs=check.runs)
    except UnsupportedProblemError as exc:
        if on_presets():  # every integrator runs the belt's linear presets
            return CheckResult(
                cls.name,
                check.name,
                FAILED,
                f"refused a belt preset: {exc}",
                time.perf_counter() - tic,
                runs=check.runs,
            )
        # an integrator that cannot run this problem says so at setup: reported, not a failure
        return CheckResult(
            cls.name, check.name, SKIPPED, f"refused at setup: {exc}", time.perf_counter() - tic, runs=check.runs
        )
    except Exception as exc:  # a failing check, whatever the integrator raised
        seconds = time.perf_counter() - tic
        if gap is not None:
            return CheckResult(cls.name, check.name, XFAIL, f"known gap: {gap}", seconds, runs=check.runs)
        detail = (
            _assertion_note(exc)
            if isinstance(exc, AssertionError)
            else f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=3)}"
        )
        return CheckResult(cls.name, check.name, FAILED, detail, seconds, runs=check.runs)
    seconds = time.perf_counter() - tic
    if gap is not None:
        return CheckResult(cls.name, check.name, XPASS, f"declared gap passes: {gap}", seconds, runs=check.runs)
    return CheckResult(cls.name, check.name, PASSED, check.doc, seconds, runs=check.runs)


def _assertion_note(exc: AssertionError) -> str:
    """A failed check's note: its message, or for a bare ``assert`` (a plug-in's own, inside its code) the
    line that failed, so that no failure is reported with an empty note."""
    if str(exc).strip():
        return str(exc)
    frame = traceback.extract_tb(exc.__traceback__)[-1]
    return f"assertion failed without a message at {frame.filename}:{frame.lineno}: {frame.line}"


def check_integrator(
    obj: Any,
    checks: Sequence[str] | None = None,
    *,
    raise_on_failure: bool = False,
    problem: str | dict[str, Any] | None = None,
    options: dict[str, Any] | None = None,
) -> list[CheckResult]:
    """Run the conformance kit on one integrator.

    Parameters
    ----------
    obj
        A registry name, an :class:`Integrator` subclass or a configured instance.
    checks
        Names of the checks to run (default: all; see :data:`nsbench.testing.CHECKS`).
    raise_on_failure
        Raise ``AssertionError`` listing the failed checks instead of returning.
    problem
        The problem family the checks run on: a registry name or a dict of the
        name and the parameters every case shares, e.g. ``{"name": "chain",
        "n": 5}`` (default: ``'two-dof'``). On the belt oscillators the checks use
        its presets 1-4; any other problem (``'bouncing-ball'``, a plug-in's) is
        checked as given against ``reference``, the belt-only checks skipped, and
        an integrator that refuses it at ``setup`` has every check skipped with its reason.
    options
        Integrator options, set on ``obj``. These, and the settings of a
        configured instance that differ from the defaults, are *the options
        given*, and every check runs with them: the single-configuration checks
        (``event-times``, ``cubic-event-times``, ``stuck-stays-stuck``,
        ``energy-balance``) at exactly that configuration instead of the middle
        accuracy level, and the stepped checks (``declared-order``,
        ``convergence``) around a given step option (:func:`plan` says what
        will run). A failure note names the options its run used.

    Returns
    -------
    list of CheckResult
        One per check, in the kit's order.

    Raises
    ------
    ConfigError
        An unknown check, problem or option, or a bad option value, before any check runs.
    """
    integ, given = configure(obj, options)
    family = problem_family(problem)  # a bad problem fails here, before any check
    selected = checks_for(integ, checks)
    results = [run_check(integ, check, {"name": family[0], **family[1]}, given) for check in selected]
    failed = [r for r in results if r.status == FAILED]
    if raise_on_failure and failed:
        raise AssertionError("; ".join(f"{r.check}: {r.message}" for r in failed))
    return results


def parametrize_with_checks(integrators: Iterable[Any], problem: str | dict[str, Any] | None = None):
    """A ``pytest.mark.parametrize`` over every (integrator, check) pair.

    ``problem`` is the problem family of the checks, as for :func:`check_integrator`.

    The test receives the integrator and a callable that runs the check on a
    fresh copy of it. Checks that do not apply are skipped and declared known
    gaps are expected failures, each with its reason::

        from nsbench.testing import parametrize_with_checks

        @parametrize_with_checks(["exact", MyIntegrator(h=0.01)])
        def test_conformance(integrator, check):
            check(integrator)
    """
    import pytest

    name, shared = problem_family(problem)
    family = {"name": name, **shared}
    suffix = "" if problem is None else "-" + "-".join([name, *(f"{k}{v}" for k, v in shared.items())])
    params = []
    for obj in integrators:
        integ = as_integrator(obj)
        cls = type(integ)
        gaps = known_gaps(integ)
        for check in CHECKS:
            marks = []
            with checking_on(family):
                reason = check.skip_reason(cls.capabilities)
            if reason is not None:
                marks.append(pytest.mark.skip(reason=reason))
            elif check.name in gaps:
                marks.append(pytest.mark.xfail(reason=gaps[check.name], strict=False))
            params.append(
                pytest.param(integ, _Runner(check, family), id=f"{cls.name}-{check.name}{suffix}", marks=marks)
            )
    return pytest.mark.parametrize("integrator, check", params)


class _Runner:
    """Callable handed to the test: runs one check on a fresh copy of the integrator."""

    def __init__(self, check: Check, family: dict[str, Any]) -> None:
        self.check = check
        self.family = family

    def __call__(self, integ: Integrator) -> None:
        import pytest

        with checking_on(self.family), checking_with(given_options(integ)):
            try:
                self.check.run(type(integ).from_config(integ.config()))
            except CheckSkipped as exc:
                pytest.skip(str(exc))
            except UnsupportedProblemError as exc:
                if on_presets():
                    raise
                pytest.skip(f"refused at setup: {exc}")

    def __repr__(self) -> str:
        return f"<check {self.check.name}>"
