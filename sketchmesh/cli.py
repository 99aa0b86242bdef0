"""Command-line entry point: ``sketchmesh [SUBCOMMAND] ...``.

With no subcommand it starts the desktop app. Each layer registers its own subcommands
from a module that is cheap to import (argparse only; torch and Qt are imported inside the
command functions), so ``sketchmesh --help`` and ``sketchmesh infer`` never load torch.

Registration contract: every module in :data:`REGISTRARS` defines
``register(commands, bench)`` where ``commands`` and ``bench`` are argparse sub-parser
collections (top-level commands and ``bench`` sub-commands). Each parser it adds sets
``func=callable(args) -> int`` via ``set_defaults``.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from engine.cliutil import one_line_errors, run_guarded


def gui_value_options() -> set[str]:
    """The GUI's options that take a value, read from :func:`app.main.add_gui_arguments` (which imports only argparse)."""
    from app.main import add_gui_arguments

    parser = argparse.ArgumentParser(add_help=False)
    add_gui_arguments(parser)
    return {s for action in parser._actions if action.nargs != 0 for s in action.option_strings}


def is_gui_run(argv: list[str]) -> bool:
    """Whether ``sketchmesh ARGV`` starts the desktop app (no subcommand), judged before argparse and numpy load:
    every word is an option or the value of a GUI option that takes one."""
    takes_value = gui_value_options()
    words = iter(argv)
    for word in words:
        if word in takes_value:
            next(words, None)
        elif not word.startswith("-"):
            return False
    return True


def limit_blas_threads_for_the_gui(argv: list[str]) -> bool:
    """One OpenBLAS thread when ``sketchmesh ARGV`` starts the app and numpy is not loaded yet (OpenBLAS reads
    ``OPENBLAS_NUM_THREADS`` once, when numpy loads it); returns whether it set it.

    The engine's matrices are small, and OpenBLAS's own threads, which spin while they wait, stalled the UI thread
    for 231-640 ms when other processes kept both cores busy (57-106 ms with one thread, the engine no slower idle;
    README, "The app under the pen", session-load). A value the user set wins. Nothing is set in a process that
    already loaded numpy (a test calling :func:`main`), so the setting never leaks into its child processes.
    """
    if "numpy" in sys.modules or "OPENBLAS_NUM_THREADS" in os.environ or not is_gui_run(argv):
        return False
    os.environ["OPENBLAS_NUM_THREADS"] = "1"
    return True


REGISTRARS = (
    "engine.cli",  # infer, bench engine
    "training.cli.data",  # data, bench data
    "training.cli.train",  # train, eval, export, import-models, average
    "training.cli.bench",  # bench renderer, bench fit
    "training.cli.router",  # router train | eval | export | set
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="sketchmesh",
        description="Sketch-based modelling: one freehand sketch in, a 3D mesh out. "
        "Run with no subcommand to start the desktop app.",
    )
    one_line_errors(parser)
    parser.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    from app.main import add_gui_arguments

    add_gui_arguments(parser)
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    bench_parser = commands.add_parser("bench", help="benchmarks that print tables and write JSON")
    bench = bench_parser.add_subparsers(dest="bench_command", metavar="BENCHMARK", required=True)
    for name in REGISTRARS:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            missing = exc.name or ""
            if not (name == missing or name.startswith(missing + ".")):
                raise  # a real missing dependency inside the module
            continue  # that layer is not installed (e.g. the frozen app ships without training)
        module.register(commands, bench)
    return parser


def main(argv: list[str] | None = None) -> int:
    limit_blas_threads_for_the_gui(sys.argv[1:] if argv is None else list(argv))
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        from app.main import run_gui

        return run_guarded(run_gui, args)
    return run_guarded(args.func, args)
