"""What every module of the bench shares, and imports nothing of the bench: keys, labels, field texts.

A leaf, so that the suite, its targets, the references and the execution of a
case can all use them without importing one another.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any


def stable_key(obj: Any) -> str:
    """A short hash of a JSON-serialisable object (sorted keys), stable across processes."""
    text = json.dumps(obj, sort_keys=True, separators=(",", ":"), default=float)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def jsonable(obj: Any) -> str:
    """``obj`` as JSON with sorted keys (numpy numbers as floats): the stored form of options and parameters."""
    return json.dumps(obj, sort_keys=True, default=float)


def got(value: Any) -> str:
    """``int 5``, ``str 'abc'``: the type and (shortened) value of a bad field."""
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 60 else text[:57] + '...'}"


def problem_label(config: dict[str, Any]) -> str:
    """``'two-dof/2'`` plus any parameter overrides; a problem without cases by its name (``'bouncing-ball'``).

    ``dimensional`` is said only of a problem with presets: one without cases has one form.
    """
    case = config.get("case")
    label = config["name"] if case is None else f"{config['name']}/{case}"
    if config.get("dimensional") and case is not None:
        label += " dimensional"
    params = config.get("params") or {}
    if params:
        label += " " + " ".join(
            f"{k}={v:g}" if not isinstance(v, str) else f"{k}={v}"  # law=weakening
            for k, v in sorted(params.items())
        )
    return label
