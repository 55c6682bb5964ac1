"""The ``dense_states`` column: a run's dense and final states as JSON text, read back bit for bit."""

from __future__ import annotations

import json

import numpy as np
import pytest

from nsbench.bench import metrics


def test_dense_states_read_back_bit_for_bit_nan_and_infinities_included():
    rng = np.random.default_rng(53)
    dense = rng.standard_normal((4, 7)) * 10.0 ** rng.integers(-300, 300, (4, 7))
    dense[1, 2], dense[2, 3], dense[3, 4] = np.nan, np.inf, -0.0
    final = np.array([1 / 3, -2.5e-310, np.nextafter(1.0, 2.0), -np.inf])
    text = metrics.dense_states_text(dense, final)
    back, back_final = metrics.dense_states_arrays(text)
    assert back.shape == (4, 7) and back.dtype == float
    assert back.tobytes() == dense.astype("<f8").tobytes() and back_final.tobytes() == final.tobytes()
    record = json.loads(text)
    assert (record["encoding"], record["n_states"], record["n_points"]) == ("float64-le-base64", 4, 7)
    # compact: about 11 characters a value (base64 of 8 bytes), where a float's repr takes up to 24
    assert len(text) < 11 * (dense.size + final.size) + 200


@pytest.mark.parametrize(
    "text",
    [
        "not json",
        "[1, 2]",
        '{"encoding": "float32", "n_states": 1, "n_points": 1, "dense": "", "final": ""}',
        '{"encoding": "float64-le-base64", "n_states": 2, "n_points": 1, "dense": "AAAAAAAA8D8=", "final": ""}',
        '{"encoding": "float64-le-base64", "n_states": 1, "n_points": 1, "dense": "%%%", "final": "AAAAAAAA8D8="}',
        '{"encoding": "float64-le-base64", "n_states": 0, "n_points": 1, "dense": "", "final": ""}',
    ],
)
def test_damaged_dense_states_are_refused(text):
    with pytest.raises(ValueError):
        metrics.dense_states_arrays(text)


def test_states_that_do_not_fit_are_not_written():
    with pytest.raises(ValueError, match="do not fit"):
        metrics.dense_states_text(np.zeros((2, 3)), np.zeros(3))
