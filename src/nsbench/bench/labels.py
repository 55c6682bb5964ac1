"""How a configuration is named to a reader: by its options (``h=0.0001``), never by a level's index."""

from __future__ import annotations

import json
from typing import Any

import pandas as pd


def options_text(text: Any) -> str:
    """An options cell (JSON text or a dict) for reading: ``rtol=1e-09, atol=1e-11`` (floats to 4 significant
    digits); ``defaults`` for no options."""
    options = text if isinstance(text, dict) else None
    if options is None:
        try:
            options = json.loads(text) if isinstance(text, str) and text.startswith("{") else None
        except ValueError:
            options = None
    if not isinstance(options, dict):
        return "" if text is None or text is pd.NA else str(text)
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in options.items())


def configuration(integrator: str, options: Any) -> str:
    """An integrator at its options, as a legend names it: ``henon-rk4 (h=0.0001)``, ``exact`` alone when it
    has none."""
    text = options_text(options)
    return f"{integrator} ({text})" if text else integrator
