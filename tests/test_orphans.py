"""sidar_torch.orphans: the "exit when the parent dies" helper every render fan-out uses."""

import os
import select
import signal
import subprocess
import sys
import time

from conftest import alive
from hang_guard import CHILD_WALL_SECONDS, cap_cpu

from sidar_torch.orphans import open_descriptors, release_inherited_descriptors

# A child forks a grandchild that calls exit_with_parent, prints its pid and then blocks for good;
# argv[1] = "signal" arms Linux's parent-death signal, "watch" relies on the getppid thread alone.
FAMILY = """
import os, sys, time
from sidar_torch.orphans import exit_with_parent
parent = os.getpid()
if os.fork() == 0:
    exit_with_parent(parent, death_signal=sys.argv[1] == "signal")
    print(os.getpid(), flush=True)
    time.sleep(600)
    os._exit(0)
time.sleep(600)
"""

# The same, but a thread of the child forks the grandchild (as when a render pool is started from a
# thread) and ends; the child prints "thread ended" after it, then lives on.
FAMILY_BY_A_THREAD = """
import os, sys, threading, time
from sidar_torch.orphans import exit_with_parent
parent = os.getpid()

def fork():
    if os.fork() == 0:
        exit_with_parent(parent, death_signal=False)
        print(os.getpid(), flush=True)
        time.sleep(600)
        os._exit(0)

thread = threading.Thread(target=fork)
thread.start()
thread.join()
time.sleep(0.5)
print("thread ended", flush=True)
time.sleep(600)
"""


def _grandchild_outlives_its_parent(mode, family=FAMILY, stop=False):
    """Whether the grandchild of ``family`` lives on 5 s after its parent is killed (the grandchild is
    stopped with ``SIGSTOP`` first if ``stop``); ended here if it does."""
    child = subprocess.Popen([sys.executable, "-c", family, mode], stdout=subprocess.PIPE, text=True)
    grandchild = int(child.stdout.readline())
    if family is FAMILY_BY_A_THREAD:
        assert child.stdout.readline() == "thread ended\n"
        assert alive(grandchild), "the grandchild ended with the thread that forked it, not with its parent"
    if stop:
        os.kill(grandchild, signal.SIGSTOP)
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and alive(grandchild):
        time.sleep(0.05)
    if alive(grandchild):
        os.kill(grandchild, signal.SIGKILL)
        return True
    return False


def test_a_child_ends_when_its_parent_is_killed_with_or_without_the_death_signal():
    assert not _grandchild_outlives_its_parent("signal")
    assert not _grandchild_outlives_its_parent("watch")


def test_a_stopped_child_ends_when_its_parent_is_killed_whichever_thread_forked_it():
    # issue 48: forked by a thread (no SIGKILL death signal), a child stopped with SIGSTOP when its parent
    # was killed stayed stopped for good, reparented to pid 1: its watching thread never ran.
    assert not _grandchild_outlives_its_parent("signal", stop=True)
    assert not _grandchild_outlives_its_parent("thread", FAMILY_BY_A_THREAD, stop=True)
    assert not _grandchild_outlives_its_parent("thread", FAMILY_BY_A_THREAD)


def test_a_child_whose_parent_died_before_the_call_ends_at_once():
    run = subprocess.run([sys.executable, "-c", "import os\nfrom sidar_torch.orphans import exit_with_parent\n"
                          "exit_with_parent(os.getppid() + 1)\nprint('still here')"],
                         capture_output=True, text=True, preexec_fn=cap_cpu(60), timeout=CHILD_WALL_SECONDS)
    assert run.returncode == 1 and "still here" not in run.stdout


def test_released_descriptors_point_at_dev_null_and_keep_their_numbers(tmp_path):
    read_end, write_end = os.pipe()
    report_read, report_write = os.pipe()
    path = tmp_path / "kept.txt"
    with open(path, "w") as kept:
        assert {read_end, write_end, kept.fileno()} <= open_descriptors()
        pid = os.fork()
        if pid == 0:  # the child lets go of the pipe, keeps the file and its report pipe, and lives on
            try:
                release_inherited_descriptors({read_end, write_end})
                ok = (os.readlink(f"/proc/self/fd/{write_end}") == os.devnull
                      and os.readlink(f"/proc/self/fd/{kept.fileno()}") == str(path))
                os.write(report_write, b"ok" if ok else b"no")
                time.sleep(60)
            finally:
                os._exit(0)
        try:
            os.close(write_end)
            os.close(report_write)
            assert os.read(report_read, 2) == b"ok"
            ready, _, _ = select.select([read_end], [], [], 5.0)
            assert ready and os.read(read_end, 1) == b""  # end of file: the living child holds no write end
            assert alive(pid)
        finally:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            os.close(read_end)
            os.close(report_read)
