"""Compiled once per machine: two processes that need the same function at the same moment compile it once."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import time

# A module of its own (its own disk cache in its __pycache__), with a function long enough to compile
# (about a second) that two processes started together would both compile it without the lock.
_BODY = "\n".join(f"    s = s * 0.5 + math.sin(x + {i}.0) * {i + 1}.0" for i in range(150))
MODULE = f"""
import math
from nsbench.model.compile import jit


@jit
def slow(x):
    s = 0.0
{_BODY}
    return s
"""

# Each process imports numba and the module, waits for the go file, then calls the function once and
# prints how many times it compiled it (numba broadcasts numba:compile only for a real compilation;
# a load from the disk cache broadcasts nothing).
RUNNER = """
import os, sys, time
sys.path.insert(0, sys.argv[1])
from numba.core import event
import slow_module
count = []


class Count(event.Listener):
    def on_start(self, e):
        if getattr(e.data["dispatcher"], "py_func", None) is slow_module.slow.py_func:
            count.append(e)

    def on_end(self, e):
        pass


go = os.path.join(sys.argv[1], "go")
while not os.path.exists(go):
    time.sleep(0.005)
with event.install_listener("numba:compile", Count()):
    value = slow_module.slow(0.25)
print(len(count), value)
"""


def test_two_processes_compile_a_function_once_and_get_the_same_code(tmp_path):
    (tmp_path / "slow_module.py").write_text(MODULE)
    (tmp_path / "runner.py").write_text(textwrap.dedent(RUNNER))
    procs = [
        subprocess.Popen(
            [sys.executable, str(tmp_path / "runner.py"), str(tmp_path)], stdout=subprocess.PIPE, text=True
        )
        for _ in range(2)
    ]
    time.sleep(0.5)  # both import numba and nsbench meanwhile; the go file then starts them together
    (tmp_path / "go").write_text("")
    outs = [p.communicate(timeout=600)[0].split() for p in procs]
    assert all(p.returncode == 0 for p in procs)
    compiled = sorted(int(o[0]) for o in outs)
    assert compiled == [0, 1], f"compilations per process: {compiled} (without the lock both compile)"
    assert outs[0][1] == outs[1][1]  # the loaded code is the compiled code
    assert list((tmp_path / "__pycache__").glob("*.nsbench-lock"))  # beside the function's disk cache
