import subprocess
import sys


def test_help_lists_every_command() -> None:
    out = subprocess.run([sys.executable, "-m", "fogsf", "--help"], check=True,
                         capture_output=True, text=True).stdout
    for name in ("simulate", "inspect", "train", "export", "replay", "diagnose"):
        assert name in out
