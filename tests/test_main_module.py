"""``python -m btfsm`` is the ``btfsm`` command."""
import subprocess
import sys


def test_python_m_btfsm_runs_the_cli():
    done = subprocess.run([sys.executable, "-m", "btfsm", "check", "pickplace3", "--property", "no-dead-states", "-q"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "no-dead-states" in done.stdout and "holds" in done.stdout


def test_python_m_btfsm_bad_input_exits_2_without_traceback():
    done = subprocess.run([sys.executable, "-m", "btfsm", "check", "no-such-model"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith("btfsm check: error: no such file or built-in model")
