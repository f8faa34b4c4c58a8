"""compare/running/gate.py: a worker waits for the driver's word before its clocks start and says
when they have stopped (fast tier)."""
from __future__ import annotations

import os

import pytest

from compare.running import gate


def test_ungated_a_worker_starts_at_once_and_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.delenv(gate.GATE_ENV, raising=False)
    g = gate.Gate(tmp_path)
    assert not g.gated
    g.release()                                   # before wait: nothing to release
    assert g.window == []
    g.wait()
    g.release()
    assert len(g.window) == 2 and g.window[0] <= g.window[1] and list(tmp_path.iterdir()) == []


def test_gated_it_says_ready_waits_for_a_byte_and_says_timed(tmp_path, monkeypatch):
    r, w = os.pipe()
    monkeypatch.setenv(gate.GATE_ENV, str(r))
    g = gate.Gate(tmp_path)
    assert g.gated and gate.GATE_ENV not in os.environ          # one cell per gate
    assert not gate.Gate(tmp_path).gated
    os.write(w, b"x")                            # the driver opens the gate
    g.wait()
    assert (tmp_path / gate.READY).exists() and not (tmp_path / gate.TIMED).exists()
    g.release()
    assert (tmp_path / gate.TIMED).exists()
    os.fstat(r)                                   # held open: the worker parks on it
    os.close(w)                                   # the driver lets it exit
    g.park()
    with pytest.raises(OSError):                  # closed once the driver's end was
        os.fstat(r)


def test_a_parked_worker_idles_until_the_driver_closes_its_pipe(tmp_path, monkeypatch):
    import threading
    r, w = os.pipe()
    monkeypatch.setenv(gate.GATE_ENV, str(r))
    g = gate.Gate(tmp_path)
    os.write(w, b"x")
    g.wait()
    g.release()
    done = threading.Event()
    t = threading.Thread(target=lambda: (g.park(), done.set()))
    t.start()
    assert not done.wait(0.3)                     # record written, exit held back
    os.close(w)
    assert done.wait(5) and g.fd is None
    t.join()
    monkeypatch.delenv(gate.GATE_ENV, raising=False)
    gate.Gate(tmp_path).park()                    # ungated: returns at once


def test_a_driver_that_is_gone_starts_no_clock(tmp_path, monkeypatch):
    r, w = os.pipe()
    monkeypatch.setenv(gate.GATE_ENV, str(r))
    g = gate.Gate(tmp_path)
    os.close(w)                                   # the driver died without a word
    with pytest.raises(SystemExit, match="closed the gate"):
        g.wait()
    assert g.window == []
    os.close(r)


def test_a_malformed_descriptor_is_no_gate(tmp_path, monkeypatch):
    monkeypatch.setenv(gate.GATE_ENV, "fd3")
    assert not gate.Gate(tmp_path).gated
