"""The argument parser and argument types shared by the subcommands.

Every subcommand spells its options the same way:

* ``--env ID`` is the environment (``--env a,b --env c`` and ``all`` where several make sense);
* ``--num-envs K`` is the number of episodes simulated together (the batch size);
* ``--episodes N`` is a number of episodes (evaluated, recorded);
* counts accept ``2e6``, ``2_000_000`` or ``2000000``.

Older spellings (a positional id, ``--envs``, ``--ids``, ``--n-envs``, ``--batch``,
``--timesteps``) still work as hidden aliases and print a one-line deprecation warning.
Options are never abbreviated (``--step`` is an error, not ``--steps``), a misspelled option is
answered with the usage of its subcommand and the closest option, and help text wraps at the
terminal width (at most 100 columns).
"""

from __future__ import annotations

import argparse
import difflib
import re
import shutil
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

#: Help text never gets wider than this, however wide the terminal.
MAX_HELP_WIDTH = 100

#: Largest count accepted (64-bit signed integers).
MAX_COUNT = 2**63 - 1


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Keeps the layout of descriptions (examples) and wraps at the terminal width, at most :data:`MAX_HELP_WIDTH` columns."""

    def __init__(self, prog: str, indent_increment: int = 2, max_help_position: int = 30, width: int | None = None) -> None:
        if width is None:
            width = min(shutil.get_terminal_size().columns, MAX_HELP_WIDTH) - 2
        super().__init__(prog, indent_increment, max_help_position, width)


class Parser(argparse.ArgumentParser):
    """``ArgumentParser`` without abbreviations, with :class:`HelpFormatter` and "did you mean" hints.

    Subparsers made by :meth:`add_subparsers` are parsers of this class too.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs["allow_abbrev"] = False
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self.nested: dict[str, Parser] = {}

    def add_nested(self, name: str, **kwargs: Any) -> Parser:
        """Add a subcommand to a command that takes positional arguments of its own.

        ``bluesky-gym results pack DIR...`` beside ``bluesky-gym results DIR...``: when the first
        argument is ``name``, the returned parser parses the rest; otherwise this one parses all
        (a directory called ``name`` is then written ``./name``).
        """
        kwargs.setdefault("prog", f"{self.prog} {name}")
        line = f"  {self.prog} {name} ...  {kwargs.pop('help', '')}".rstrip()
        self.epilog = f"{self.epilog or 'subcommands (each with --help):'}\n{line}"
        parser = Parser(**kwargs)
        self.nested[name] = parser
        return parser

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: Any = None
    ) -> tuple[Any, list[str]]:
        """Parse as ``ArgumentParser`` does, and record in ``cli_parser`` the innermost (sub)parser that parsed."""
        if args is not None and len(args) and args[0] in self.nested:
            return self.nested[args[0]].parse_known_args(list(args[1:]), namespace)
        parsed, extras = super().parse_known_args(args, namespace)
        if getattr(parsed, "cli_parser", None) is None:
            parsed.cli_parser = self
        return parsed, extras

    def option_names(self) -> list[str]:
        """The option strings shown in the help (hidden aliases left out)."""
        return list(dict.fromkeys(re.findall(r"(?<![\w-])(--?[A-Za-z][\w-]*)", self.format_help())))

    def unrecognized(self, extras: Sequence[str]) -> NoReturn:
        """Exit with this parser's usage for unrecognized arguments, naming the closest option of each."""
        hints = []
        for word in extras:
            if word.startswith("-"):
                close = difflib.get_close_matches(word.split("=", 1)[0], self.option_names(), n=1, cutoff=0.6)
                if close:
                    hints.append(f"{word.split('=', 1)[0]} -> did you mean {close[0]}?")
        message = f"unrecognized arguments: {' '.join(extras)}"
        self.error(f"{message} ({'; '.join(hints)})" if hints else message)


def warn(prog: str, message: str) -> None:
    """Print a one-line warning of a command on stderr."""
    print(f"{prog}: warning: {message}", file=sys.stderr)


class _DeprecatedOption(argparse.Action):
    """A hidden old spelling of an option: stores into the new option's destination, with a warning."""

    def __init__(self, option_strings: list[str], dest: str, replacement: str = "", extend: bool = False, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, **kwargs)
        self.replacement = replacement
        self.extend = extend

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: Any, option_string: str | None = None) -> None:
        warn(parser.prog, f"{option_string} is deprecated; use {self.replacement}")
        if self.extend:
            current = getattr(namespace, self.dest, None)
            setattr(namespace, self.dest, [*(current or []), *values])
        else:
            setattr(namespace, self.dest, values)


def deprecated_alias(parser: argparse.ArgumentParser, old: str, new: str, dest: str, extend: bool = False, **kwargs: Any) -> None:
    """Add ``old`` as a hidden alias of the option ``new`` (same ``dest``), printing a deprecation warning when used.

    Args:
        parser: The subcommand's parser.
        old: The old option string (``"--n-envs"``).
        new: The option that replaces it (``"--num-envs"``).
        dest: The destination both store into.
        extend: Add the values to a list instead of replacing it (for repeatable options).
        **kwargs: ``type``, ``nargs``, ``metavar`` of the old option.

    """
    parser.add_argument(
        old, dest=dest, action=_DeprecatedOption, replacement=new, extend=extend, help=argparse.SUPPRESS, default=argparse.SUPPRESS, **kwargs
    )


def env_list(text: str) -> list[str]:
    """Parse a comma-separated list of environment ids (``all`` allowed)."""
    ids = [t.strip() for t in text.split(",") if t.strip()]
    if not ids:
        raise argparse.ArgumentTypeError(f"expected environment ids, got {text!r}")
    return ids


def add_env_option(parser: argparse.ArgumentParser, *, several: bool = False, required: bool = True, help: str | None = None) -> None:  # noqa: A002
    """Add ``--env``; for one id, also the deprecated positional ``ID``.

    Args:
        parser: The subcommand's parser.
        several: Accept several ids (repeatable, comma lists, ``all``); the value is then a list.
        required: Whether an id must be given (checked by :func:`chosen_env`).
        help: Help text of ``--env``.

    """
    if several:
        parser.add_argument(
            "--env", dest="env", action="extend", type=env_list, metavar="ID", help=help or "environment ids (repeatable, comma-separated) or 'all'"
        )
    else:
        parser.add_argument("--env", dest="env", metavar="ID", help=help or "environment id, e.g. DescentEnv-v0")
        parser.add_argument("env_positional", nargs="?", metavar="ID", help=argparse.SUPPRESS)
    parser.set_defaults(env_required=required)


def chosen_env(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Resolve the deprecated positional id into ``args.env`` (one warning), and check that an id was given."""
    positional = getattr(args, "env_positional", None)
    if positional is not None:
        if args.env is not None and args.env != positional:
            parser.error(f"two environments given: {positional} and --env {args.env}")
        warn(parser.prog, f"the positional environment id is deprecated; use --env {positional}")
        args.env = positional
    if args.env is None and getattr(args, "env_required", False):
        parser.error("the following arguments are required: --env")


def whole_number(text: str) -> int:
    """Parse a whole number, also written as ``2e6``, ``2_000_000`` or ``100.0``."""
    try:
        value = int(text)
    except ValueError:
        try:
            number = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number (e.g. 250000 or 2e6), got {text!r}") from None
        if not number.is_integer():
            raise argparse.ArgumentTypeError(f"expected a whole number (e.g. 250000 or 2e6), got {text!r}") from None
        value = int(number)
    if abs(value) > MAX_COUNT:
        raise argparse.ArgumentTypeError(f"must be below 2**63, got {text!r}")
    return value


def positive_int(text: str) -> int:
    """Parse an integer >= 1 (``2e6`` is accepted)."""
    value = whole_number(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return value


def non_negative_int(text: str) -> int:
    """Parse an integer >= 0 (``2e6`` is accepted)."""
    value = whole_number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """Parse a number > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return value
