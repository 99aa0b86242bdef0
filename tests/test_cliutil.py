"""Shared CLI plumbing: validated argument types and the one-line error guard."""

import argparse
import math
import os
import subprocess
import sys

import pytest

from engine.cliutil import float_in, int_in, one_line_errors, positive_int, run_guarded, unit_float
from engine.errors import EmptySketchError


@pytest.mark.parametrize("parse, text, value", [
    (positive_int, "3", 3), (int_in(0, 4), "0", 0), (int_in(0, 4), "4", 4),
    (unit_float, "0.25", 0.25), (float_in(0.0, math.inf), "1e6", 1e6),
])
def test_types_accept(parse, text, value):
    assert parse(text) == value


@pytest.mark.parametrize("parse, text", [
    (positive_int, "0"), (positive_int, "x"), (positive_int, "1.5"), (int_in(0, 4), "5"),
    (unit_float, "1.01"), (unit_float, "nan"), (float_in(0.0, math.inf), "inf"), (float_in(0.0, 1.0), "-0.1"),
])
def test_types_reject_with_argparse_errors(parse, text):
    with pytest.raises(argparse.ArgumentTypeError):
        parse(text)


def test_one_line_errors_report_unknown_flags_on_one_line(capsys):
    parser = one_line_errors(argparse.ArgumentParser(prog="tool"))
    parser.add_argument("--n", type=positive_int)
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(["--n", "2", "--bogus"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unrecognized arguments: --bogus" in err and "usage" not in err


def _raise(exc):
    def func(args):
        raise exc
    return func


@pytest.mark.parametrize("exc, code, text", [
    (EmptySketchError("the sketch is empty"), 2, "sketchmesh: error: the sketch is empty"),
    (KeyboardInterrupt(), 130, "sketchmesh: interrupted"),
    (RuntimeError("boom"), 1, "sketchmesh: error: RuntimeError: boom"),
])
def test_run_guarded_turns_errors_into_one_line_and_an_exit_code(exc, code, text, capsys, monkeypatch):
    monkeypatch.delenv("SKETCHMESH_DEBUG", raising=False)
    assert run_guarded(_raise(exc), argparse.Namespace(debug=False)) == code
    err = capsys.readouterr().err
    assert err.strip().startswith(text) and "Traceback" not in err and err.count("\n") == 1


def test_run_guarded_passes_results_and_debug_reraises():
    assert run_guarded(lambda args: None, argparse.Namespace()) == 0
    assert run_guarded(lambda args: 3, argparse.Namespace()) == 3
    with pytest.raises(RuntimeError):
        run_guarded(_raise(RuntimeError("boom")), argparse.Namespace(debug=True))


def test_output_checks_name_the_problem_and_leave_nothing(tmp_path):
    from engine.cliutil import check_output_dir, check_output_file
    from engine.errors import OutputError

    (tmp_path / "afile").write_text("x")
    cases = [
        (check_output_file, tmp_path / "afile" / "r.json", "afile is a file, not a folder"),
        (check_output_file, tmp_path / "afile" / "a" / "b" / "r.json", "afile is a file, not a folder"),
        (check_output_file, tmp_path, "is a folder, expected a file name"),
        (check_output_dir, tmp_path / "afile", "is a file, expected a folder"),
        (check_output_dir, tmp_path / "afile" / "d", "afile is a file, not a folder"),
        (check_output_file, "/proc/sketchmesh-test/r.json", "cannot write in /proc"),  # root cannot either
    ]
    for check, path, needle in cases:
        with pytest.raises(OutputError, match=needle) as exc:
            check(path, "--flag")
        assert str(exc.value).startswith(f"--flag {path}: ")
    assert check_output_file(tmp_path / "new" / "r.json") == tmp_path / "new" / "r.json"
    assert check_output_dir(tmp_path / "new2") == tmp_path / "new2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["afile"]  # the checks wrote nothing that stays


def test_run_guarded_names_the_file_of_an_os_error(capsys, monkeypatch):
    monkeypatch.delenv("SKETCHMESH_DEBUG", raising=False)
    rc = run_guarded(_raise(PermissionError(13, "Permission denied", "/x/out.obj")), argparse.Namespace(debug=False))
    assert rc == 1 and capsys.readouterr().err == "sketchmesh: error: /x/out.obj: Permission denied\n"


def test_run_guarded_puts_a_multi_line_message_on_one_line(capsys, monkeypatch):
    from engine.errors import ModelError

    monkeypatch.delenv("SKETCHMESH_DEBUG", raising=False)
    exc = ModelError("weights do not fit: Error(s) in loading state_dict:\n\tsize mismatch for w")
    assert run_guarded(_raise(exc), argparse.Namespace(debug=False)) == 2
    assert capsys.readouterr().err == "sketchmesh: error: weights do not fit: Error(s) in loading state_dict: size mismatch for w\n"


@pytest.mark.parametrize("argv, gui", [
    ([], True),
    (["--open", "sketch.png"], True),
    (["--report", "r.json", "--open", "infer", "--debug"], True),  # "infer" is --open's value here, not a command
    (["--models", "eval"], True),
    (["infer", "x.png", "-o", "y.obj"], False),
    (["--debug", "bench", "engine"], False),
    (["--models", "m", "eval", "--data", "d"], False),
])
def test_is_gui_run_tells_the_app_from_the_subcommands(argv, gui):
    from sketchmesh.cli import is_gui_run

    assert is_gui_run(argv) is gui


@pytest.mark.parametrize("argv, env, expect", [
    (["--open", "s.png"], None, "1"),  # the app: one OpenBLAS thread
    (["infer", "s.png"], None, "unset"),  # a command: numpy's default
    (["--open", "s.png"], "3", "3"),  # the user's own value wins
])
def test_the_app_sets_one_openblas_thread_before_numpy_loads(argv, env, expect):
    code = ("import sys\n"
            "from sketchmesh.cli import limit_blas_threads_for_the_gui\n"
            "assert 'numpy' not in sys.modules, 'numpy loaded before the thread count could be set'\n"
            "limit_blas_threads_for_the_gui(sys.argv[1:])\n"
            "import os\n"
            "print(os.environ.get('OPENBLAS_NUM_THREADS', 'unset'))\n")
    environ = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if env is not None:
        environ["OPENBLAS_NUM_THREADS"] = env
    out = subprocess.run([sys.executable, "-c", code, *argv], capture_output=True, text=True, env=environ, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == expect


def test_a_process_with_numpy_loaded_is_left_alone(monkeypatch):
    """A test (or any caller) that already loaded numpy must not pass the setting on to its child processes."""
    import numpy  # noqa: F401

    from sketchmesh.cli import limit_blas_threads_for_the_gui

    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    assert limit_blas_threads_for_the_gui(["--open", "s.png"]) is False
    assert "OPENBLAS_NUM_THREADS" not in os.environ
