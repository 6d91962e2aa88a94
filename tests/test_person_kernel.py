"""The compiled loops over envs whose people differ (heartpole.person_kernel): numba's disk cache keeps them
(a second process compiles nothing), and their ``overlay`` argument refuses what it cannot mean."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys

import pytest

from heartpole import person_kernel

USE_THE_PEOPLE_LOOPS = """
import json
import numpy as np
from numba.core import event
import heartpole

with event.install_recorder("numba:compile") as recorder:
    vector = heartpole.HeartPoleVectorEnv(4, people="default")
    vector.reset(seed=0)
    vector.step(np.zeros(4, dtype=np.int64))
    single = heartpole.HeartPole(people="default")
    single.reset(seed=0)
    single.step(0)
functions = {
    f"{e.data['dispatcher'].py_func.__module__}.{e.data['dispatcher'].py_func.__qualname__}"
    for _, e in recorder.buffer
    if e.is_start
}
print(json.dumps(sorted(f for f in functions if f.startswith("heartpole."))))
"""


@pytest.mark.slow  # two fresh processes, the first compiling every loop of people='default' (tens of seconds)
def test_a_second_process_loads_the_people_loops_from_the_disk_cache(tmp_path) -> None:
    """The loops of people="default" (vector env step and reset, single env step) are compiled by the first
    process that uses them and loaded from numba's disk cache by the next: it compiles nothing of HeartPole's.
    (The positions of the people's numbers are in the loops' argument types, which key the cache.)"""
    environment = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba-cache")}
    environment.pop("NUMBA_DISABLE_JIT", None)

    def compiled() -> list[str]:
        done = subprocess.run(
            [sys.executable, "-c", USE_THE_PEOPLE_LOOPS], capture_output=True, text=True, check=True, env=environment
        )
        return list(json.loads(done.stdout))

    first = [name for name in compiled() if name.startswith("heartpole.person_kernel.")]
    for loop in ("step_envs", "reset_envs", "step_one"):  # the first process compiled each of them
        assert any(name.endswith(loop) for name in first), (loop, first)
    assert compiled() == []


def test_overlay_for_refuses_positions_it_cannot_place() -> None:
    """An overlay needs one column per position and distinct positions; it names what it got otherwise."""
    overlay = person_kernel.overlay_for([79, 80, 84], [0, 0, 1])
    assert overlay.shape == (0,) and overlay.dtype.itemsize == 8
    assert person_kernel._positions(overlay.dtype.fields.items()) == ((79, 80, 84), (0, 0, 1))
    for positions, columns in (([79, 80], [0]), ([79, 79], [0, 1]), ([79], [-1]), ([-1], [0])):
        with pytest.raises(ValueError, match=re.escape(f"got positions {positions} and columns {columns}")):
            person_kernel.overlay_for(positions, columns)
