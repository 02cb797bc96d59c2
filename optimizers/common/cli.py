"""Command-line errors in argparse's form, shared by every command of the project.

A wrong input (an unknown env id, a bad hyperparameter, a missing file) ends a command with one
line ``<prog>: error: <message>`` on stderr and exit status 2, as argparse does for a bad
option, instead of a traceback. Only the validation and construction phase of a command is
wrapped: once the run starts, an exception is a bug and keeps its traceback::

    args = parser.parse_args(argv)
    with user_input_errors(parser):
        config = validate(args)          # ValueError / KeyError -> "prog: error: ...", exit 2
    run(config)                          # anything raised here keeps its traceback
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["USER_INPUT_ERRORS", "user_input_errors", "error_message", "check_env"]

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
