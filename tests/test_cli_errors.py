"""How `cli.main` reports what went wrong: a user's error in one line (exit 2), a bug of ours with
its traceback and a request to report it (exit 1)."""

from __future__ import annotations

import errno

import pytest

from edgedog import cli
from edgedog.commands import info


def run_main(monkeypatch, capsys, raised: BaseException, argv=("info", "somewhere")):
    def failing(args):
        raise raised

    monkeypatch.setattr(info, "run", failing)
    code = cli.main(list(argv))
    return code, capsys.readouterr().err


def test_an_os_error_is_one_line_naming_the_file(monkeypatch, capsys):
    code, err = run_main(monkeypatch, capsys, PermissionError(errno.EACCES, "Permission denied", "/x/y"))
    assert code == 2 and err == "edgedog: error: /x/y: Permission denied\n"


def test_an_internal_bug_shows_its_traceback_and_asks_for_a_report(monkeypatch, capsys):
    code, err = run_main(monkeypatch, capsys, ZeroDivisionError("division by zero"))
    assert code == 1
    assert "Traceback" in err and "ZeroDivisionError" in err
    assert err.strip().splitlines()[-1].startswith("edgedog: internal error: this is a bug")


def test_ctrl_c_without_a_resume_hint_is_one_line(monkeypatch, capsys):
    code, err = run_main(monkeypatch, capsys, KeyboardInterrupt())
    assert code == cli.INTERRUPTED == 130 and err == "edgedog: error: interrupted\n"


def masked_interrupt() -> RuntimeError:
    """What torch.save's zip writer raises when Ctrl-C interrupts it: its clean-up fails while
    the KeyboardInterrupt unwinds, and the interrupt is left only in the context."""
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:
            raise RuntimeError("PytorchStreamWriter failed writing central directory") from None
    except RuntimeError as error:
        return error


def test_ctrl_c_masked_by_a_library_clean_up_is_still_an_interrupt(monkeypatch, capsys):
    code, err = run_main(monkeypatch, capsys, masked_interrupt())
    assert code == cli.INTERRUPTED and err == "edgedog: error: interrupted\n"


def test_usage_errors_are_one_line(capsys):
    with pytest.raises(SystemExit) as exited:
        cli.main(["train", "--bogus"])
    err = capsys.readouterr().err
    assert exited.value.code == 2
    assert err.count("\n") == 1 and err.startswith("edgedog: error: edgedog train: ") and "--help" in err


def test_help_still_prints_the_usage(capsys):
    with pytest.raises(SystemExit) as exited:
        cli.main(["train", "--help"])
    assert exited.value.code == 0 and "usage: edgedog train" in capsys.readouterr().out
