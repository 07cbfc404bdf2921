"""The studies' analysis computes numbers and never loads Jinja: only the reports'
modules word them (:mod:`glshade.study.templating`)."""

from __future__ import annotations

import subprocess
import sys


def test_the_analysis_never_loads_jinja():
    code = (
        "import sys, glshade.study.findings_numbers, glshade.study.pmd_numbers, "
        "glshade.study.finding3_numbers; print('jinja2' in sys.modules)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "False"
