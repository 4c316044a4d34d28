"""The command's heap is frozen for the garbage collector only when the command is the process.

``veriloc-rt`` (``main()`` without argv) ends its process: the objects it imported and built
live to the end, and the interpreter's shutdown collected them for 0.3 s of every command
(docs/notes/performance-history.md, resume). A caller running commands in-process (``main(argv)``, the tests)
keeps its collector as it was.
"""

from __future__ import annotations

import gc
import subprocess
import sys
from pathlib import Path

from veriloc_rt.cli import main

ROOT = Path(__file__).resolve().parents[2]


def test_the_whole_process_command_freezes_its_heap():
    code = ("import gc, sys; from veriloc_rt.cli import main; sys.argv = ['veriloc-rt', 'config', "
            "'show']; before = gc.get_freeze_count(); main(); "
            "print(before, gc.get_freeze_count(), file=sys.stderr)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT,
                       check=True)
    before, after = map(int, r.stderr.split())
    assert before == 0 and after > 0


def test_an_in_process_command_leaves_the_collector_alone(capsys):
    before = gc.get_freeze_count()
    assert main(["config", "show"]) == 0
    assert gc.get_freeze_count() == before
    assert '"seed"' in capsys.readouterr().out
