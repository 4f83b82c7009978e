"""SidarAugment's render pool (num_workers >= 1): same outputs as in-process rendering, its lifetime, its errors."""

import copy
import os
import pickle
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import torch

import sidar_torch.augment_pool
from sidar_torch import SidarAugment

pytestmark = pytest.mark.gl  # renders

TINY = (48, 64)


def augment(num_workers, seed=0, **overrides):
    return SidarAugment("misaligned", seed=seed, num_workers=num_workers,
                        **{"image_size": TINY, "n_views": 2, "n_occluders": (1, 2), **overrides})


def assert_same_batch(a, b):
    assert a.keys() == b.keys()
    for key in a:
        assert torch.equal(a[key], b[key]), key


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie (exited, not yet reaped) counts as gone.
    with open(f"/proc/{pid}/stat") as stat:
        return stat.read().split(")")[-1].split()[0] != "Z"


def wait_gone(pids, seconds=10.0):
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and any(alive(p) for p in pids):
        time.sleep(0.1)
    return [p for p in pids if alive(p)]


def test_a_pool_gives_the_same_outputs_as_one_process_call_after_call():
    images = torch.rand(5, 3, 60, 100)  # fitted to 48 x 64 in the workers
    serial, pooled = augment(0), augment(2)
    with pooled:
        for _ in range(2):
            assert_same_batch(serial(images), pooled(images))
        workers = [p.pid for p in pooled._pool.processes]
        assert len(set(workers)) == 2 and os.getpid() not in workers
        # Generators too; the pool is reused, not restarted.
        assert_same_batch(serial(images, generator=torch.Generator().manual_seed(3)),
                          pooled(images, generator=torch.Generator().manual_seed(3)))
        assert [p.pid for p in pooled._pool.processes] == workers
        assert serial.calls == pooled.calls == 2
    assert pooled._pool is None
    assert wait_gone(workers) == []
    # A closed module starts a new pool at its next call, and continues the same sequence.
    assert_same_batch(serial(images[:2].to(torch.float64)), pooled(images[:2].to(torch.float64)))
    pooled.close()


def test_pickled_and_copied_modules_start_their_own_pool_and_continue_the_sequence():
    images = torch.rand(3, 3, *TINY)
    module = augment(2, seed=4)
    module(images)
    pool = module._pool
    for clone in (pickle.loads(pickle.dumps(module)), copy.deepcopy(module)):
        assert clone._pool is None and clone.calls == 1 and clone.num_workers == 2
        expected = augment(0, seed=4)
        expected.calls = 1
        assert_same_batch(clone(images), expected(images))
        assert clone._pool is not pool
        clone.close()
    restored = augment(2, seed=4)
    restored.load_state_dict(module.state_dict())
    assert restored.calls == 1 and restored._pool is None
    assert module._pool is pool and pool.usable
    module.close()
    assert not pool.usable


def test_an_error_in_a_worker_is_raised_by_forward_with_the_workers_message(monkeypatch):
    original = sidar_torch.augment_pool.sample_sequence

    def failing(config, rng):
        if rng.integers(0, 3) == 0:  # some images of the batch
            raise ValueError("scene refused in the worker")
        return original(config, rng)

    monkeypatch.setattr(sidar_torch.augment_pool, "sample_sequence", failing)  # before the fork: workers have it
    module = augment(2)
    with module, pytest.raises(ValueError, match="scene refused in the worker") as raised:
        module(torch.rand(8, 3, *TINY))
    assert any("render worker" in note and "failing" in note for note in raised.value.__notes__)


def test_a_dead_worker_raises_and_the_next_call_restarts_the_pool():
    images = torch.rand(2, 3, *TINY)
    module = augment(2)
    first = module(images)
    victim = module._pool.processes[0]
    os.kill(victim.pid, signal.SIGKILL)
    victim.join(5)
    with pytest.raises(RuntimeError, match=r"render worker \(pid \d+\) died with exit code -9"):
        module(images)
    assert module._pool is None or not module._pool.usable
    again = module(images)  # call 2: a new pool
    expected = augment(0)
    expected.calls = 2
    assert_same_batch(again, expected(images))
    assert not torch.equal(first["images"], again["images"])
    module.close()


@pytest.mark.parametrize("ending", ["exit", "kill"])
def test_workers_exit_when_the_parent_ends(ending):
    # "exit": the interpreter exits without close(); "kill": the parent is killed with SIGKILL.
    script = (
        "import os, signal, sys, torch\n"
        "from sidar_torch import SidarAugment\n"
        f"aug = SidarAugment('misaligned', seed=0, num_workers=2, image_size={TINY}, n_views=2)\n"
        f"aug(torch.rand(2, 3, *{TINY}))\n"
        "print(*[p.pid for p in aug._pool.processes], flush=True)\n"
        f"{'os.kill(os.getpid(), signal.SIGKILL)' if ending == 'kill' else 'sys.exit(0)'}\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                         cwd=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    pids = [int(p) for p in run.stdout.split()]
    assert len(pids) == 2, run.stderr
    assert wait_gone(pids) == []
