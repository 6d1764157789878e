"""Stop signals: SIGTERM, SIGHUP and SIGQUIT raise Stopped, but never inside an import."""

from __future__ import annotations

import importlib
import os
import signal
import sys
import time

import pytest

from sim import stops
from sim.stops import Stopped, stop_handlers

MODULE = """
import os, signal, time
os.kill(os.getpid(), signal.SIGTERM)
time.sleep(0.2)
DONE = True
"""


def _import_signalled(tmp_path, name):
    (tmp_path / f"{name}.py").write_text(MODULE)
    sys.path.insert(0, str(tmp_path))
    try:
        with pytest.raises(Stopped) as info, stop_handlers():
            importlib.import_module(name)
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline:
                time.sleep(0.01)
        return info.value
    finally:
        sys.path.remove(str(tmp_path))


def test_a_signal_during_an_import_waits_for_the_import(tmp_path):
    exc = _import_signalled(tmp_path, "_stops_probe_a")
    assert exc.signum == signal.SIGTERM and exc.exit_code == 143
    assert getattr(sys.modules.get("_stops_probe_a"), "DONE", False)  # the import finished first


def test_the_negative_control_an_immediate_raise_breaks_the_import(tmp_path, monkeypatch):
    monkeypatch.setattr(stops, "_importing", lambda frame: False)
    _import_signalled(tmp_path, "_stops_probe_b")
    assert "_stops_probe_b" not in sys.modules  # the module's own code was cut short


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGHUP, 129), (signal.SIGQUIT, 131)])
def test_each_stop_signal_raises_with_its_exit_code_and_the_handlers_come_back(sig, code):
    before = signal.getsignal(sig)
    with pytest.raises(Stopped) as info, stop_handlers():
        os.kill(os.getpid(), sig)
        time.sleep(1)
    assert info.value.exit_code == code
    assert signal.getsignal(sig) is before
