"""The vector environments' worlds shared out to worker processes (``workers=W``, docs/rl.md).

A vector environment of B worlds steps them as one batch in one process. With ``workers=W`` it
splits them into W contiguous shares, and each worker process steps its share as one batch; the
environment sends each worker its share of the actions, and joins their answers along the world
axis. Each world is stepped by the same code from the same seed as in one process, so the joined
answers are the one-process environment's, bit for bit (tests/test_env_workers.py).

The environments' own step over a share of worlds is a *stepper* (``swarmscene.env``): an object
made by ``make(num_envs, *args)`` with ``reset(seeds)``, returning the observations and the
per-world arrays of the infos, and ``step(actions)``, returning a :class:`Stepped`. :class:`Shards`
has the same two methods over all B worlds.
"""

from __future__ import annotations

import multiprocessing
import pickle
import signal
import weakref
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numpy as np

JOIN_SECONDS = 5.0
"""How long :meth:`Shards.close` waits for a worker to end before it terminates it."""


class Stepped(NamedTuple):
    """One step of B worlds, before the infos take Gymnasium's vector form."""

    observations: np.ndarray
    """(B, N, D)."""
    rewards: np.ndarray
    """(B,) or (B, N)."""
    terminated: np.ndarray
    truncated: np.ndarray
    ended: list[tuple[int, dict[str, Any]]]
    """(world, its info) for each world with an info (its episode ended), in the worlds' order."""
    arrays: dict[str, np.ndarray]
    """Per-world arrays of the infos, (B, ...)."""


def joined(parts: Sequence[Stepped], starts: Sequence[int]) -> Stepped:
    """The shares' steps as one step of all the worlds: share k's first world is world ``starts[k]``."""
    ended = [(start + b, info) for part, start in zip(parts, starts, strict=True) for b, info in part.ended]
    return Stepped(np.concatenate([part.observations for part in parts]),
                   np.concatenate([part.rewards for part in parts]),
                   np.concatenate([part.terminated for part in parts]),
                   np.concatenate([part.truncated for part in parts]),
                   ended, _joined_arrays([part.arrays for part in parts]))


def _joined_arrays(parts: Sequence[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {key: np.concatenate([part[key] for part in parts]) for key in parts[0]}


def shares(num_envs: int, workers: int) -> list[range]:
    """The worlds of each worker: ``workers`` contiguous ranges, their sizes differing by at most one."""
    bounds = np.linspace(0, num_envs, workers + 1).round().astype(int)
    return [range(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)]


class Shards:
    """B worlds stepped by ``workers`` processes, each a stepper over its share (module docstring).

    Args:
        make: the stepper's class (or any picklable callable): ``make(share_size, *args)``.
        num_envs: B.
        workers: the number of processes, 2 to B.
        context: the ``multiprocessing`` start method (None: the platform's default, as
            Gymnasium's ``AsyncVectorEnv``); with ``"spawn"`` or ``"forkserver"`` the script that
            makes the environment needs an ``if __name__ == "__main__":`` guard.
        args: the rest of ``make``'s arguments (the config, options...).
    """

    def __init__(self, make: Callable[..., Any], num_envs: int, workers: int, context: str | None,
                 args: tuple[Any, ...]) -> None:
        self.shares = shares(num_envs, workers)
        mp: Any = multiprocessing.get_context(context)  # (typeshed's BaseContext lacks Process)
        self._pipes: list[Any] = []
        self._processes: list[Any] = []
        for k, share in enumerate(self.shares):
            here, there = mp.Pipe()
            process = mp.Process(target=_serve, args=(there, make, (len(share), *args)),
                                 name=f"swarmscene-worlds-{k}", daemon=True)
            process.start()
            there.close()
            self._pipes.append(here)
            self._processes.append(process)
        self._close = weakref.finalize(self, _stop, self._pipes, self._processes)
        try:
            self._answers([True] * workers)  # each worker made its stepper
        except BaseException:
            self.close()
            raise

    def reset(self, seeds: Sequence[int | None]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Every world's ``reset`` from its seed (one per world); the observations and arrays joined."""
        parts = self._ask("reset", [list(seeds[share.start:share.stop]) for share in self.shares])
        return np.concatenate([obs for obs, _ in parts]), _joined_arrays([arrays for _, arrays in parts])

    def step(self, actions: np.ndarray) -> Stepped:
        """Every world's ``step`` with its row of ``actions`` (B, ...); the shares' steps joined."""
        parts = self._ask("step", [actions[share.start:share.stop] for share in self.shares])
        return joined(parts, [share.start for share in self.shares])

    def close(self) -> None:
        """End the workers (idempotent)."""
        self._close()

    def _ask(self, command: str, payloads: list[Any]) -> list[Any]:
        """Send each worker its payload, then read every answer (so that the pipes stay in step
        even where one worker fails); a worker's error is raised here."""
        if not self._close.alive:
            raise RuntimeError("the vector environment is closed")
        sent = [_sent(pipe, (command, payload)) for pipe, payload in zip(self._pipes, payloads, strict=True)]
        try:
            return self._answers(sent)
        except (KeyboardInterrupt, SystemExit):  # the answers unread: the pipes would be out of step
            self.close()
            raise

    def _answers(self, sent: list[bool]) -> list[Any]:
        """Each worker's answer (one whose message could not be sent has none); the first error raised."""
        answers, failure = [], None
        for k, pipe in enumerate(self._pipes):
            try:
                if not sent[k]:
                    raise EOFError
                ok, answer = pipe.recv()
            except (EOFError, OSError):
                process = self._processes[k]
                process.join(JOIN_SECONDS)
                ok, answer = False, RuntimeError(
                    f"worker {k} of the vector environment ended unexpectedly (exit code {process.exitcode})")
            if not ok and failure is None:
                failure = answer
            answers.append(answer)
        if failure is not None:
            raise failure
        return answers


def _sent(pipe: Any, message: tuple[str, Any]) -> bool:
    """Whether ``message`` went into the pipe (not where its worker has ended)."""
    try:
        pipe.send(message)
    except (BrokenPipeError, OSError):
        return False
    return True


def _serve(pipe: Any, make: Callable[..., Any], args: tuple[Any, ...]) -> None:
    """A worker: make the stepper, then answer ``(command, payload)`` until ``close`` or until the
    environment's end of the pipe is gone; each answer is ``(True, result)`` or ``(False, error)``."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the environment's to handle: it closes us
    try:
        stepper = make(*args)
    except Exception as error:  # noqa: BLE001 - every error goes back to the environment
        pipe.send((False, _portable(error)))
        return
    pipe.send((True, None))
    while True:
        try:
            command, payload = pipe.recv()
        except (EOFError, OSError):
            return
        if command == "close":
            return
        try:
            answer = (True, getattr(stepper, command)(payload))
        except Exception as error:  # noqa: BLE001 - as above
            answer = (False, _portable(error))
        pipe.send(answer)


def _portable(error: Exception) -> Exception:
    """``error`` itself where it survives pickling (its type and message as raised in one process),
    else a RuntimeError with its type's name and message."""
    try:
        pickle.loads(pickle.dumps(error))
    except Exception:  # noqa: BLE001 - any failure to pickle means: send its text
        return RuntimeError(f"{type(error).__name__}: {error}")
    return error


def _stop(pipes: list[Any], processes: list[Any]) -> None:
    """Ask every worker to end, wait for it, then terminate the ones still running."""
    for pipe in pipes:
        _sent(pipe, ("close", None))
    for pipe, process in zip(pipes, processes, strict=True):
        process.join(JOIN_SECONDS)
        if process.is_alive():
            process.terminate()
            process.join(JOIN_SECONDS)
        pipe.close()
