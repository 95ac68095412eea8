"""The suite's test groups hold: tests marked ``xdist_group`` run in one test process.

``scripts/test`` runs pytest-xdist with ``--dist loadgroup``; a module whose fixtures are costly (a service
started with its worker processes, answers located once for many tests) is grouped so that one process makes
them. pytest 9.2 with pytest-xdist 3.8 dropped the groups without a word (each process made the fixtures
again); this runs a small suite the same way and fails where grouping does not happen.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

GROUPED = textwrap.dedent(
    """
    import os

    import pytest

    pytestmark = pytest.mark.xdist_group("one")


    @pytest.mark.parametrize("k", range(6))
    def test_note_the_worker(k):
        with open(os.path.join(os.environ["GROUP_PROBE_DIR"], str(k)), "w") as f:
            f.write(os.environ["PYTEST_XDIST_WORKER"])
    """
)


def test_grouped_tests_run_in_one_process(tmp_path):
    suite = tmp_path / "suite"
    suite.mkdir()
    (suite / "test_grouped.py").write_text(GROUPED)
    (suite / "test_other.py").write_text("def test_a():\n    pass\n\n\ndef test_b():\n    pass\n")
    probe = tmp_path / "workers"
    probe.mkdir()
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-q",
            "-n",
            "2",
            "--dist",
            "loadgroup",
            "-p",
            "no:cacheprovider",
            ".",
        ],
        cwd=suite,
        env={**os.environ, "GROUP_PROBE_DIR": str(probe)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    notes = [p.read_text() for p in probe.iterdir()]
    assert len(notes) == 6, run.stdout
    workers = set(notes)
    assert len(workers) == 1, f"the group's six tests ran in {sorted(workers)}: xdist_group is not honoured"
