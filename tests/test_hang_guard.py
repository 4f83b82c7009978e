"""The suite's hang guard (``tests/hang_guard.py``, issue 34 item 6): it catches a loop that spins and a
call that blocks, and lets a slow but progressing computation on a loaded machine finish."""

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from hang_guard import cap_cpu, no_hang

TESTS = Path(__file__).resolve().parent


def test_a_busy_loop_is_caught_after_its_cpu_time():
    start = time.process_time()
    with pytest.raises(TimeoutError, match=r"spinning: used more than 0.5 s of CPU time"):
        with no_hang(0.5):
            while True:
                pass
    assert 0.5 <= time.process_time() - start < 5


@pytest.mark.parametrize("block", ["lock", "sleep"])
def test_a_blocking_call_is_caught_after_the_idle_time(block):
    start = time.monotonic()
    with pytest.raises(TimeoutError, match=r"blocked: used under 0.1 s of CPU time in 1 s of wall time"):
        with no_hang(60, idle_seconds=1):
            if block == "lock":  # a deadlock: the lock is already held by this thread
                lock = threading.Lock()
                lock.acquire()
                lock.acquire()
            else:
                time.sleep(3600)
    assert time.monotonic() - start < 30


def test_the_guard_leaves_the_signal_handler_and_nothing_running():
    before = signal.getsignal(signal.SIGALRM)
    threads = threading.active_count()
    with no_hang(5):
        sum(range(1000))
    with pytest.raises(ZeroDivisionError):
        with no_hang(5):
            1 / 0
    assert signal.getsignal(signal.SIGALRM) is before and threading.active_count() == threads


SLOW = """
import json, sys, time
sys.path.insert(0, {tests!r})
from hang_guard import cap_cpu, no_hang
wall, cpu = time.monotonic(), time.process_time()
with no_hang(1.0):
    total = 0
    while time.process_time() - cpu < 0.25:  # 0.25 s of CPU: about 2.5 s of wall time at a tenth of a core
        total += 1
print(json.dumps({{"wall": time.monotonic() - wall, "cpu": time.process_time() - cpu}}))
"""


def test_a_slow_but_progressing_computation_on_a_loaded_machine_is_not_caught():
    """The machine is loaded as load 20 loads 2 cores: the guarded process shares one core with 9 busy
    ones (``sched_setaffinity``), so it gets about a tenth of it, and its 0.25 s of CPU take seconds
    of wall time, more than its 1 s CPU allowance: a wall-clock guard of the same limit would fire."""
    cpu = sorted(os.sched_getaffinity(0))[0]
    pin = lambda: os.sched_setaffinity(0, {cpu})  # noqa: E731
    busy = [subprocess.Popen([sys.executable, "-S", "-c", "while True: pass"], preexec_fn=pin) for _ in range(9)]
    try:
        run = subprocess.run([sys.executable, "-S", "-c", SLOW.format(tests=str(TESTS))], preexec_fn=pin,
                             capture_output=True, text=True, timeout=300)
    finally:
        for process in busy:
            process.kill()
            process.wait()
    assert run.returncode == 0, run.stderr
    measured = json.loads(run.stdout)
    assert measured["wall"] > 1.0, measured  # the load made it slower than its CPU allowance


def test_a_child_that_spins_ends_after_its_cpu_time():
    start = time.monotonic()
    run = subprocess.run([sys.executable, "-S", "-c", "while True: pass"], preexec_fn=cap_cpu(1), timeout=300)
    assert run.returncode == -signal.SIGXCPU and time.monotonic() - start < 300
