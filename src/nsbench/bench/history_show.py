"""``nsbench history show`` as a function: :func:`show_history` runs a :class:`HistoryShowRequest`.

The runs of a history store (:mod:`nsbench.bench.history`) listed in commit order per machine
and environment, the steps flagged between consecutive runs (the statistics of ``nsbench
compare``), and, if asked, the long table, the steps and a figure written to a folder. The
command line (:mod:`nsbench.cli.history`) maps its arguments onto the request; the tables and
what was written are printed here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from nsbench.errors import ConfigError
from nsbench.inputs import check_output_dir, parse_number

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

    from nsbench.bench.history import Entry

#: What ``--out`` receives, each replaced, never written through a link.
WRITTEN = ("history.csv", "steps.csv", "history.png", "history.svg", "history.pdf")
#: The columns of the flagged steps printed.
STEP_COLUMNS = (
    "commit",
    "previous",
    "problem",
    "integrator",
    "options",
    "time_ratio",
    "cpu_ratio",
    "nfev_ratio",
    "err_ratio",
    "flags",
)


@dataclass(frozen=True)
class HistoryShowRequest:
    """What ``history show`` asks for, checked at its construction (``factor``, ``confidence`` and
    ``out``: a :class:`~nsbench.errors.ConfigError` naming the value before the store is read).

    Attributes
    ----------
    store
        The history store.
    machine, environment, problem, integrator
        Only these runs and rows (``None``: all).
    factor, confidence
        Smallest ratio that counts as a change; confidence of a flagged time change.
    out
        Folder to write ``history.csv``, ``steps.csv`` and the figure to (``None``: none written).
    check
        The outcome fails when the newest run of a machine and environment has a flagged step.
    """

    store: str = "nsbench-history"
    machine: str | None = None
    environment: str | None = None
    problem: str | None = None
    integrator: str | None = None
    factor: float = 1.5
    confidence: float = 0.99
    out: str | None = None
    check: bool = False

    def __post_init__(self) -> None:
        from nsbench.bench.compare import check_thresholds

        factor, confidence = (
            parse_number(str(self.factor), "--factor"),
            parse_number(str(self.confidence), "--confidence"),
        )
        check_thresholds(factor, confidence)
        object.__setattr__(self, "factor", factor)
        object.__setattr__(self, "confidence", confidence)
        if self.out:
            check_output_dir(self.out, "--out")
            from nsbench.files import refuse_links

            refuse_links(self.out, WRITTEN)

    @property
    def filters(self) -> dict[str, str | None]:
        return dict(
            machine=self.machine, environment=self.environment, problem=self.problem, integrator=self.integrator
        )


@dataclass(frozen=True)
class HistoryShowOutcome:
    """The flagged steps, and whether the newest run has one (with ``check``: exit status 1)."""

    steps: pd.DataFrame
    newest_flagged: bool

    @property
    def exit_code(self) -> int:
        return 1 if self.newest_flagged else 0


def show_history(request: HistoryShowRequest) -> HistoryShowOutcome:
    """Print the store's runs and the flagged steps, and write the tables and the figure to ``out``.

    Raises
    ------
    ConfigError
        The store holds no run (of that machine and environment).
    """
    import pandas as pd

    from nsbench.bench import history
    from nsbench.bench.report import markdown_table

    found = history.entries(request.store, request.machine, request.environment)
    if not found:
        raise ConfigError(
            f"history store {request.store!r} holds no run"
            + (" of that machine and environment" if request.machine or request.environment else "")
        )
    print(markdown_table(pd.DataFrame([_listed(e) for e in found])))
    tab = history.table(request.store, **request.filters)
    flagged = history.steps(request.store, factor=request.factor, confidence=request.confidence, **request.filters)
    print(f"\n{len(flagged)} flagged step(s) (factor {request.factor:g}, confidence {request.confidence:g})")
    if len(flagged):
        print(markdown_table(flagged[list(STEP_COLUMNS)]))
    if request.out:
        written = _write(tab, flagged, Path(request.out))
        print("written: " + ", ".join(str(p) for p in written))
    newest = {(e.machine, e.environment): e.short for e in found}
    on_newest = any(newest.get((r.machine, r.environment)) == r.commit for r in flagged.itertuples())
    return HistoryShowOutcome(flagged, request.check and on_newest)


def _listed(e: Entry) -> dict[str, str]:
    return {
        "machine": e.machine,
        "environment": e.environment,
        "commit": e.short,
        "commit time": e.commit_time,
        "added": e.added,
        "cpu": e.cpu,
    }


def _write(tab: pd.DataFrame, flagged: pd.DataFrame, out: Path) -> list[Path]:
    from nsbench.bench import history

    out.mkdir(parents=True, exist_ok=True)
    tab.to_csv(out / "history.csv", index=False)
    flagged.to_csv(out / "steps.csv", index=False)
    written = [out / "history.csv", out / "steps.csv"]
    if len(tab):
        fig = history.figure(tab, flagged, out)
        written += [fig.png, fig.svg]
    return written
