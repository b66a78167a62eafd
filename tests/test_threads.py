"""The command line's threading policy: its own process runs numpy's BLAS, OpenMP and OpenCV
on one thread each, unless the user set their variables (``brokenness._threads``)."""

from __future__ import annotations

import importlib.metadata
import os
import subprocess
import sys

import pytest

from brokenness._threads import OPENCV_THREADS_VAR, THREAD_ENV_VARS
from brokenness.cli import main as cli_main

_PROBE = (
    "import os; from brokenness._threads import single_threaded_process; "
    "single_threaded_process(); import cv2, numpy; "
    "print(cv2.getNumThreads(), os.environ['OPENBLAS_NUM_THREADS'], os.environ['MKL_NUM_THREADS'])"
)


def _clean_env(**kept: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in (*THREAD_ENV_VARS, OPENCV_THREADS_VAR)}
    env.update(kept)
    return env


def test_the_process_policy_gives_opencv_and_blas_one_thread() -> None:
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=_clean_env(), capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["1", "1", "1"]


def test_a_users_own_thread_settings_are_kept() -> None:
    env = _clean_env(**{OPENCV_THREADS_VAR: "2", "MKL_NUM_THREADS": "3"})
    out = subprocess.run(
        [sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["2", "1", "3"]


def test_the_command_applies_the_policy_before_running(monkeypatch: pytest.MonkeyPatch) -> None:
    calls: list[str] = []
    monkeypatch.setattr(cli_main, "single_threaded_process", lambda: calls.append("policy"))
    monkeypatch.setattr(cli_main, "main", lambda: calls.append("main") or 0)
    assert cli_main.console() == 0
    assert calls == ["policy", "main"]


def test_the_installed_command_and_python_m_are_the_console_entry() -> None:
    (script,) = importlib.metadata.entry_points(group="console_scripts", name="brokenness")
    assert script.value == "brokenness.cli.main:console"
    code = (
        "import os, sys, runpy\n"
        "import brokenness.cli.main as m\n"
        f"m.main = lambda: print('ran', os.environ.get({OPENCV_THREADS_VAR!r}),"
        " 'cv2' in sys.modules) or 0\n"
        "runpy.run_module('brokenness', run_name='__main__')"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=_clean_env(), capture_output=True, text=True
    )
    # the module entry sets the policy, then runs main, before OpenCV is loaded
    assert out.returncode == 0 and out.stdout.split() == ["ran", "1", "False"]


def test_main_called_from_python_leaves_the_environment_alone(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for name in (*THREAD_ENV_VARS, OPENCV_THREADS_VAR):
        monkeypatch.delenv(name, raising=False)
    with pytest.raises(SystemExit):
        cli_main.main(["--version"])
    assert not any(name in os.environ for name in (*THREAD_ENV_VARS, OPENCV_THREADS_VAR))
