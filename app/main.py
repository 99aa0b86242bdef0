"""GUI entry point (placeholder wiring; the window itself lives in app.window)."""

from __future__ import annotations

import argparse


def add_gui_arguments(parser: argparse.ArgumentParser) -> None:
    """Top-level options used when ``sketchmesh`` runs with no subcommand (the GUI)."""
    parser.add_argument("--open", metavar="SKETCH", help="open a sketch image at start")
    parser.add_argument("--screenshot", metavar="PNG", help="after inference, save a window screenshot and exit")
    parser.add_argument("--models", metavar="DIR", help="model folder to use instead of the bundled one")
    parser.add_argument(
        "--report",
        metavar="JSON",
        help="play a scripted session (open, 20 strokes, undo, redo, erase, views, export), "
        "print the UI lag and per-stroke latency, write them to JSON and exit",
    )


def run_gui(args: argparse.Namespace) -> int:
    from app.window import run  # noqa: PLC0415  (Qt is imported only when the GUI starts)

    return run(args)
