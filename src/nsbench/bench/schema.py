"""The tidy schema: one row per case, these columns, in this order.

Config columns hold JSON text (the dicts that rebuild the problem and the
integrator); list columns hold one value per event of the matched prefix.
Statuses are the engine's (``success``, ``step budget exhausted``, ``event storm
(Zeno)``, ``integrator failure``) plus the runner's (``unsupported``, ``time
limit``, ``error``, ``crashed``).
"""

from __future__ import annotations

#: ``(column, meaning)`` for every column of a result row.
COLUMNS: tuple[tuple[str, str], ...] = (
    ("case_id", "stable id of (problem, integrator config, span, dense grid, step budget)"),
    ("suite", "suite name"),
    ("problem", "registered problem name"),
    ("case", "problem preset 1..4"),
    ("problem_label", "readable problem label, e.g. 'two-dof/2' or 'two-dof/2 v0=0.1'"),
    ("problem_config", "JSON: the dict that rebuilds the problem (nsbench.problem_from_config)"),
    ("integrator", "registered integrator name"),
    (
        "family",
        "the integrator's family of methods (Capabilities.family): event-driven, time-stepping, "
        "switch-model, smoothing",
    ),
    ("integrator_config", "JSON: the dict that rebuilds the integrator (nsbench.integrator_from_config)"),
    ("options", "JSON: the options the suite set (the rest are defaults)"),
    ("level", "index of the option set, loose to tight"),
    ("step_option", "name of the integrator's step/tolerance option (capabilities.step_option)"),
    ("step_value", "value of that option in this case"),
    ("t0", "start of the time span"),
    ("t_end", "end of the time span"),
    ("status", "how the case ended"),
    ("message", "why, when not success"),
    (
        "loop",
        "who ran the event loop (SimulationResult.loop): native (the integrator's own), per-arc (the core's, "
        "one advance per arc), kernel (the core's, a compiled arc kernel), whole-system",
    ),
    ("t_final", "where the run stopped"),
    (
        "nfev",
        "evaluations of the method's model: right-hand sides (one per state) for the event-driven, "
        "switch-model and smoothing methods; one-step problems (a stick/slip status solved and tested "
        "against the friction law) for moreau-jean; 0 where the method counts none (siconos), shown n/a "
        "in the tables",
    ),
    ("njev", "Jacobian evaluations"),
    ("nsteps", "steps or segments"),
    ("n_events", "events logged by the run"),
    ("counters_extra", "JSON: integrator-specific counters"),
    ("wall_time", "seconds per run: median of the timed samples (all warm: after an untimed warm-up)"),
    ("wall_time_min", "fastest timed sample (seconds per run)"),
    ("wall_time_max", "slowest timed sample (seconds per run)"),
    ("wall_spread", "relative spread of the timed samples, (max - min) / median; NaN with one sample"),
    (
        "wall_times",
        "list: seconds per run of every timed sample, in order (a sample is the mean of its `loops` "
        "runs; the warm-up and the calibration run are not among them)",
    ),
    (
        "n_repeats",
        "number of timed samples: the suite's repeats (at least 3; 5 by default) if successful, 1 if the run failed",
    ),
    (
        "loops",
        "runs per timed sample: 1 for a run of at least the suite's min_sample_time, else the first of "
        "1, 2, 5, 10, 20, ... whose runs last that long (from the calibration run)",
    ),
    (
        "integrator_time",
        "seconds inside the integrator (engine's own clock) per run: median over the timed "
        "samples; NaN if the engine does not report it",
    ),
    ("integrator_times", "list: integrator_time per run of every timed sample"),
    (
        "cpu_time",
        "CPU seconds of the worker process per run, over the same stretch as wall_time: median over "
        "the timed samples (the work done, without the time other programs held the core)",
    ),
    ("cpu_times", "list: cpu_time per run of every timed sample"),
    (
        "setup_time",
        "seconds in the integrator's setup in this case's warm-up: compilation and operators for "
        "the first case of an integrator in a worker, a cache load for the others (the report "
        "charges the integrator its largest, nsbench.bench.timing.setup_table)",
    ),
    (
        "setup_time_timed",
        "longest setup among the timed runs: near 0 when warm; a large value means "
        "compilation happened while timing (setup is never part of wall_time)",
    ),
    ("warmup_time", "seconds of the untimed warm-up run (the first tenth of the span, cold)"),
    ("reference", "name of the reference integrator, empty if none"),
    ("reference_config", "JSON: its config"),
    ("reference_status", "'ok', or why there is no usable reference"),
    (
        "ref_conditioning",
        "max switching-time change per unit change of the start positions, measured by the "
        "reference from a start moved by 1e-9; inf where that changes the event sequence",
    ),
    (
        "ref_double_floor",
        "ref_conditioning x 2.2e-16: the switching-time uncertainty of any double-precision "
        "solution from the rounding of its start; above 1e-10 the case cannot be graded in double",
    ),
    (
        "ref_certainty",
        "largest certified error bound of the reference's event times (an independent check at "
        "higher precision, nsbench.bench.reference.certified_errors); inf where the check's event "
        "sequence differs, NaN if not certified",
    ),
    ("n_ref", "events in the reference"),
    ("n_prefix", "events paired one to one from the first, up to the first missed or extra event"),
    (
        "n_matched",
        "events paired by the best alignment on (kind, block) and time: fewest unmatched events, "
        "then the smallest total time difference of its pairs (nsbench.bench.metrics.align)",
    ),
    ("n_missed", "reference events the run does not have"),
    ("n_extra", "events of the run the reference does not have"),
    (
        "first_divergence_index",
        "index of the first missed or extra event (n_prefix), -1 if the sequences are identical",
    ),
    ("first_divergence_time", "time of that event (the reference's if missed, the run's if extra), NaN if identical"),
    ("sequence_ok", "the (kind, block) sequences are identical"),
    (
        "switch_err_max",
        "max |t - t_ref| over the matched prefix, each event's error floored at the reference's "
        "certified error there (never reported below what the reference can certify)",
    ),
    ("switch_err_rms", "RMS of the same floored errors"),
    ("switch_err_median", "median of the same floored errors"),
    ("switch_digits", "significant correct digits of the worst switching time, -log10 max |dt|/|t_ref|"),
    (
        "at_ref_accuracy",
        "every |t - t_ref| of the matched prefix is within the reference's certified error "
        "there: the run's error is not measurable against this reference",
    ),
    ("final_state_err", "max-norm of the state error at t_end (NaN unless success)"),
    ("state_err_l2", "RMS over the dense points of the Euclidean state error (NaN unless success)"),
    (
        "stick_creep",
        "drift velocity off the belt per unit of stick time under an in-cone load: sum |d(x_i - v_belt t)| "
        "over consecutive dense points inside the reference's stick intervals of block i (those begun in the "
        "matched prefix) where the load, by the reference's state and by the run's own, is within the kinetic "
        "level (|R_i| <= fs_i), divided by the time they span, pooled over blocks; NaN if no two such points "
        "(nsbench.bench.metrics.stick_creep)",
    ),
    (
        "stick_drift",
        "largest position drift relative to the belt within those windows, "
        "|x_i(t) - x_i(t_a) - v_belt (t - t_a)| from a window's first dense point t_a",
    ),
    ("breakaway_err_max", "max |t - t_ref| over the break-away (slip) events of the matched prefix; NaN if none"),
    (
        "located_err_max",
        "max |t_located - t_ref| over the matched prefix: the switch times a whole-system method located "
        "itself (SystemResult.switch_times), beside the inferred ones of switch_err_max; NaN if it locates none",
    ),
    (
        "arc_err",
        "max-norm state error of a separate run on a smooth arc: started on the reference's dense "
        "state a quarter into its longest slipping arc, stopped a quarter before the arc's end, so no "
        "switch is stepped over (nsbench.bench.families.smooth_arc_error); NaN without such an arc, or if "
        "that run fails or switches",
    ),
    (
        "penetration",
        "impact problems: the largest depth below the ground at the dense points, max(0, -x); NaN for other problems",
    ),
    (
        "energy_err",
        "impact problems: |E(t_end) - E_ref(t_end)|, the energy left at the end against the "
        "reference's; NaN for other problems",
    ),
    ("event_t", "list: reference times of the matched prefix"),
    ("event_err", "list: signed switching-time errors t - t_ref of the matched prefix (as measured, not floored)"),
    (
        "event_cert",
        "list: the reference's certified error bound at each event of the matched prefix "
        "(empty if the reference is not certified)",
    ),
    ("timestamp", "UTC time the case finished"),
)

COLUMN_NAMES: tuple[str, ...] = tuple(name for name, _ in COLUMNS)
LIST_COLUMNS = ("wall_times", "integrator_times", "cpu_times", "event_t", "event_err", "event_cert")
JSON_COLUMNS = ("problem_config", "integrator_config", "options", "counters_extra", "reference_config")
RUNNER_STATUSES = ("unsupported", "time limit", "error", "crashed")


def markdown_table() -> str:
    """The column list as a Markdown table (for docs and reports)."""
    rows = ["| column | meaning |", "|---|---|"]
    rows += [f"| `{name}` | {meaning} |" for name, meaning in COLUMNS]
    return "\n".join(rows)
