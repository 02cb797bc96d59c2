"""Command-line errors in argparse's form, shared by every command of the project.

A wrong input (an unknown env id, a bad hyperparameter, a missing file) ends a command with one
line ``<prog>: error: <message>`` on stderr and exit status 2, as argparse does for a bad
option, instead of a traceback. Only the validation and construction phase of a command is
wrapped: once the run starts, an exception is a bug and keeps its traceback::

    args = parser.parse_args(argv)
    with user_input_errors(parser):
        config = validate(args)          # ValueError / KeyError -> "prog: error: ...", exit 2
    run(config)                          # anything raised here keeps its traceback

An interrupted command (Ctrl-C, or SIGTERM from a scheduler or ``kill``) ends as cleanly:
:func:`clean_interrupts` stops the executor's workers, keeps what is stored, prints one line
and exits 130 (SIGINT) or 143 (SIGTERM), the shell's codes for those signals, without a
traceback::

    with get_executor(address, workers) as ex, clean_interrupts(ex):
        run_tasks(tasks, ex, store)      # each finished task is already stored
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["USER_INPUT_ERRORS", "user_input_errors", "error_message", "check_env",
           "clean_interrupts", "Terminated", "INTERRUPTED_MESSAGE", "exit_status",
           "count_type", "seed_type", "real_type", "output_file_type", "output_dir_type",
           "input_path_type", "ray_address_type", "MAX_SEED", "MAX_COUNT"]

#: the line an interrupted command prints (on stderr) before it exits
INTERRUPTED_MESSAGE = "interrupted; run the same command to resume"

#: what validation raises for a wrong input: ValueError (bad value), KeyError (unknown name),
#: FileNotFoundError (a path that does not exist), gymnasium's registry errors (unknown id)
USER_INPUT_ERRORS: tuple[type[BaseException], ...] = (ValueError, KeyError, FileNotFoundError)


def _gym_errors() -> tuple[type[BaseException], ...]:
    try:
        from gymnasium import error
    except ImportError:
        return ()
    return (error.Error,)


def check_env(env_id: str, env_kwargs: dict | None = None) -> None:
    """Check that ``env_id`` is registered and builds with ``env_kwargs`` (then closed).

    Raises
    ------
    ValueError
        An unknown id (the message lists this project's env ids), or constructor arguments the
        env refuses.
    """
    import gymnasium as gym

    import lunar_env  # noqa: F401  (registers the ids)

    if env_id not in gym.registry:
        ours = sorted(k for k, s in gym.registry.items()
                      if str(s.entry_point).startswith("lunar_env"))
        raise ValueError(f"env {env_id!r} is not a registered Gymnasium id; this project's "
                         f"envs: {', '.join(ours)}")
    kwargs = dict(env_kwargs or {})
    try:
        env = gym.make(env_id, **kwargs)
    except TypeError as exc:  # an unknown keyword argument
        raise ValueError(f"env {env_id!r} refuses the arguments {kwargs}: {exc}") from None
    env.close()


def error_message(exc: BaseException) -> str:
    """One line for ``exc``: a KeyError's message without repr quotes, newlines joined."""
    if isinstance(exc, KeyError) and len(exc.args) == 1 and isinstance(exc.args[0], str):
        text = exc.args[0]
    else:
        text = str(exc) or type(exc).__name__
    return " ".join(text.split())


@contextmanager
def user_input_errors(parser: argparse.ArgumentParser,
                      errors: tuple[type[BaseException], ...] = (),
                      prefix: str | None = None) -> Iterator[None]:
    """Turn a wrong-input exception raised in the block into ``parser.error`` (exit status 2).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        Names the program in the message (``parser.prog``).
    errors : tuple of exception types
        Caught besides :data:`USER_INPUT_ERRORS` and ``gymnasium.error.Error`` (e.g.
        ``TypeError`` where the block only builds objects from user-given keyword arguments).
    prefix : str, optional
        Put before the message (e.g. the option the block validates: ``"--set"``).
    """
    try:
        yield
    except (*USER_INPUT_ERRORS, *_gym_errors(), *errors) as exc:
        msg = error_message(exc)
        parser.error(f"{prefix}: {msg}" if prefix else msg)


# ----------------------------------------------------------------------------- interrupts


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread by :func:`clean_interrupts` (a KeyboardInterrupt, so
    every ``except KeyboardInterrupt`` / ``finally`` on the way out runs as for a Ctrl-C)."""


def exit_status(exc: BaseException) -> int:
    """The shell's exit status of an interrupt: 143 (128 + SIGTERM) for :class:`Terminated`,
    130 (128 + SIGINT) for any other KeyboardInterrupt."""
    return 128 + (signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT)


def _raise_terminated(signum, frame) -> None:
    raise Terminated


def _stop(executor: Any) -> None:
    """Stop ``executor``'s workers now (no waiting for the tasks in flight)."""
    if executor is None:
        return
    stop = getattr(executor, "terminate", None) or getattr(executor, "close", None)
    if stop is not None:
        stop()


@contextmanager
def clean_interrupts(executor: Any = None, *, message: str = INTERRUPTED_MESSAGE,
                     on_interrupt: Callable[[], None] | None = None) -> Iterator[None]:
    """End the block's command cleanly on SIGINT (Ctrl-C) or SIGTERM.

    Inside the block SIGTERM raises :class:`Terminated` and SIGINT ``KeyboardInterrupt`` in
    the main thread (whatever their handlers were; restored on exit), so the code under way
    unwinds through its ``finally`` clauses: an atomic write either completes or leaves
    nothing, and every result stored before stays. Then, with both signals ignored (a second
    Ctrl-C does not break the clean-up): ``executor``'s workers are stopped
    (``executor.terminate()`` where it has one, else ``close()``), ``on_interrupt()`` runs,
    ``message`` is printed as one line on stderr, and the command exits with status 130
    (SIGINT) or 143 (SIGTERM).

    Parameters
    ----------
    executor : Executor, optional
        Stopped on an interrupt (e.g. :class:`~optimizers.common.executor.LocalExecutor`:
        its worker processes are killed; a Ray executor cancels its tasks and disconnects).
    message : str
        The line printed.
    on_interrupt : callable, optional
        Extra clean-up before the message (e.g. releasing a lock early).

    Raises
    ------
    SystemExit
        With status 130 or 143, after an interrupt.
    """
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield  # signals reach the main thread only: nothing to install here
        return
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    signal.signal(signal.SIGTERM, _raise_terminated)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    except KeyboardInterrupt as exc:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        try:
            _stop(executor)
            if on_interrupt is not None:
                on_interrupt()
        finally:
            print(f"\n{message}" if _after_partial_line() else message, file=sys.stderr,
                  flush=True)
        raise SystemExit(exit_status(exc)) from None
    finally:
        for s, h in old.items():
            signal.signal(s, h if h is not None else signal.SIG_DFL)


def _after_partial_line() -> bool:
    """True if stderr is a terminal (a Ctrl-C echoes ``^C`` without a newline there)."""
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


# ----------------------------------------------------------------------------- argument types

#: largest accepted ``--seed``: seeds are non-negative 64-bit integers (numpy's generators,
#: Gymnasium's seeding and the stores' keys all take them)
MAX_SEED = 2**63 - 1
#: default largest count (``--runs``, ``--generations``, ...): beyond it a typo, not a plan
MAX_COUNT = 1_000_000


def count_type(minimum: int = 1, maximum: int = MAX_COUNT) -> Callable[[str], int]:
    """An argparse ``type``: an integer in [``minimum``, ``maximum``].

    >>> count_type(1, 100)("7")
    7
    """
    def parse(text: str) -> int:
        try:
            n = int(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(
                f"{text!r} is not an integer; allowed: {minimum} to {maximum}") from None
        if not minimum <= n <= maximum:
            raise argparse.ArgumentTypeError(f"{text} is out of range; allowed: {minimum} to "
                                             f"{maximum}")
        return n

    parse.__name__ = "count"
    return parse


def seed_type(text: str) -> int:
    """An argparse ``type``: a seed, an integer in [0, 2**63 - 1]."""
    try:
        n = int(text)
    except (TypeError, ValueError):
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer; allowed: 0 to 2**63 - 1"
                                         ) from None
    if not 0 <= n <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"{text} is out of range; allowed: 0 to 2**63 - 1")
    return n


seed_type.__name__ = "seed"


def real_type(minimum: float | None = None, maximum: float | None = None, *,
              positive: bool = False) -> Callable[[str], float]:
    """An argparse ``type``: a finite number in [``minimum``, ``maximum``] (either end open
    when None); ``positive=True`` also refuses 0.

    >>> real_type(0.0)("0.25")
    0.25
    """
    import math

    low = "> 0" if positive else (f">= {minimum:g}" if minimum is not None else None)
    allowed = " and ".join(p for p in ("finite", low, None if maximum is None
                                       else f"<= {maximum:g}") if p)

    def parse(text: str) -> float:
        try:
            x = float(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"{text!r} is not a number; allowed: {allowed}"
                                             ) from None
        if (not math.isfinite(x) or (minimum is not None and x < minimum)
                or (maximum is not None and x > maximum) or (positive and x <= 0.0)):
            raise argparse.ArgumentTypeError(f"{text} is out of range; allowed: {allowed}")
        return x

    parse.__name__ = "number"
    return parse


def _require_creatable(text: str, path: str) -> None:
    """Refuse ``text`` (absolute ``path``) where its nearest existing ancestor is a file or a
    folder that cannot be written to (argparse's error)."""
    import os

    parent = os.path.dirname(path)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise argparse.ArgumentTypeError(f"{text} cannot be created: {parent} is a file, not a "
                                         "directory")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"{text} cannot be created: {parent} is not writable")


def output_dir_type(text: str) -> str:
    """An argparse ``type``: a directory this command can write (an existing one, or one it
    can create with its parents).

    Refused at once, before any work: a path naming a file, a path under a file, a folder
    that cannot be written to."""
    import os

    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a directory")
    path = os.path.abspath(text)
    if os.path.exists(path) and not os.path.isdir(path):
        raise argparse.ArgumentTypeError(f"{text} is a file, not a directory")
    if os.path.isdir(path):
        if not os.access(path, os.W_OK | os.X_OK):
            raise argparse.ArgumentTypeError(f"{text} is a directory that cannot be written")
        return text
    _require_creatable(text, path)
    return text


output_dir_type.__name__ = "directory"


def output_file_type(text: str) -> str:
    """An argparse ``type``: a file this command can write (created with its folders).

    Refused at once, before any work: an existing directory, a path under a file, a folder
    that cannot be written to."""
    import os

    if not text:
        raise argparse.ArgumentTypeError("an empty path; give a file name")
    path = os.path.abspath(text)
    if os.path.isdir(path):
        raise argparse.ArgumentTypeError(f"{text} is a directory; give a file name")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise argparse.ArgumentTypeError(f"{text} exists and cannot be written")
    _require_creatable(text, path)
    return text


output_file_type.__name__ = "file"


def input_path_type(text: str) -> str:
    """An argparse ``type``: a file or directory that exists (a model, a run, a dataset)."""
    import os

    if not text:
        raise argparse.ArgumentTypeError("an empty path; give an existing file or directory")
    if not os.path.exists(text):
        raise argparse.ArgumentTypeError(f"{text} does not exist")
    return text


input_path_type.__name__ = "path"


def ray_address_type(text: str) -> str:
    """An argparse ``type``: a Ray address: ``auto``, ``local``, ``HOST:PORT`` or
    ``ray://HOST:PORT`` (port 1 to 65535)."""
    import re

    if text in ("auto", "local"):
        return text
    m = re.fullmatch(r"(ray://)?([A-Za-z0-9](?:[A-Za-z0-9.\-]*[A-Za-z0-9])?|\[[0-9A-Fa-f:.]+\])"
                     r":(\d{1,5})", text)
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not a Ray address; allowed: 'auto', "
                                         "'local', HOST:PORT or ray://HOST:PORT")
    return text


ray_address_type.__name__ = "address"
