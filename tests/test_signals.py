"""An interrupt that something swallows on its way (a destructor, a weakref callback)
still ends the command with exit 130 (btfsm.signals)."""
import os
import signal
import types

from btfsm import cli, signals


def _swallowing_command(sig):
    def command(argv):
        try:
            os.kill(os.getpid(), sig)  # the handler raises here ...
            for _ in range(10**6):  # (delivered between bytecodes)
                pass
        except KeyboardInterrupt:
            pass  # ... and this code swallows it, as Python does in a destructor
        return 0
    return command


def test_swallowed_sigint_still_exits_130(monkeypatch, capsys):
    monkeypatch.setattr(cli, "_main", _swallowing_command(signal.SIGINT))
    assert cli.main(["check", "pickplace3"]) == 130
    assert capsys.readouterr().err.strip() == "btfsm check: interrupted"


def test_swallowed_sigterm_still_exits_143(monkeypatch, capsys):
    monkeypatch.setattr(cli, "_main", _swallowing_command(signal.SIGTERM))
    assert cli.main(["check", "pickplace3"]) == 143
    assert capsys.readouterr().err.strip() == "btfsm check: terminated"


def test_handlers_are_restored_and_nothing_is_recorded_without_a_signal():
    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    with signals.handling():
        assert signals.received() is None
        signals.check()  # nothing recorded: no exception
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_the_trial_loop_stops_on_a_recorded_interrupt(monkeypatch):
    import pytest

    from btfsm.sim.protocol import TrialSpec
    from btfsm.sim.trial import run_trial

    monkeypatch.setitem(signals._state, "received", signal.SIGINT)
    with pytest.raises(KeyboardInterrupt):
        run_trial(TrialSpec("preemptive", 1, time_limit=60.0))


def test_an_interrupt_swallowed_by_a_destructor_prints_no_traceback(monkeypatch, capsys):
    """Python reports an exception raised in a destructor through sys.unraisablehook (by
    default: "Exception ignored ... Traceback" on stderr); our own interrupt is dropped
    there, the command's one line says it."""
    import sys

    reported = []
    monkeypatch.setattr(sys, "unraisablehook", reported.append)

    class Doomed:
        def __del__(self):
            os.kill(os.getpid(), signal.SIGINT)  # the handler raises inside the destructor:
            for _ in range(10**6):  # Python runs a signal's handler between bytecodes, so the
                continue            # destructor keeps running bytecodes until it has

    def command(argv):
        Doomed()  # collected at once
        return 0

    monkeypatch.setattr(cli, "_main", command)
    assert cli.main(["check", "pickplace3"]) == 130
    assert capsys.readouterr().err.strip() == "btfsm check: interrupted"
    assert reported == []
    with signals.handling():  # anything else still reaches the previous hook
        sys.unraisablehook(types.SimpleNamespace(exc_value=ValueError("x")))
    assert [type(u.exc_value) for u in reported] == [ValueError]
