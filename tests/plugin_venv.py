"""A fresh virtual environment that sees this one's packages and has one plug-in package
installed by pip: what the plug-in tests (a component, an instrument) run glshade in."""

from __future__ import annotations

import shutil
import site
import subprocess
import venv
from pathlib import Path


def venv_with(package: Path | tuple[Path, ...], root: Path) -> Path:
    """The python of a virtual environment made in ``root`` that sees this environment's
    packages (glshade, editable or not) and has ``package`` (a folder with a
    pyproject.toml, or several) installed by pip, each built from a copy (setuptools
    leaves build/ and *.egg-info beside the sources)."""
    venv.EnvBuilder(with_pip=False).create(root)
    python = root / "bin" / "python"
    inner = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()  # fmt: skip
    outer = [*site.getsitepackages(), site.getusersitepackages()]
    lines = [f"import site; site.addsitedir({path!r})" for path in outer if Path(path).is_dir()]
    (Path(inner) / "outer_environment.pth").write_text("\n".join(lines) + "\n")
    packages = package if isinstance(package, tuple) else (package,)
    sources = [str(shutil.copytree(each, root / "source" / each.name)) for each in packages]
    install = [python, "-m", "pip", "install", "--no-deps", "--no-build-isolation", "--no-index"]
    done = subprocess.run([*install, "--quiet", *sources], capture_output=True, text=True, cwd=root)
    assert done.returncode == 0, done.stderr[-3000:]
    return python


def glshade_in(python: Path, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """``python -m glshade ARGS`` in that environment."""
    return subprocess.run(
        [python, "-m", "glshade", *args], capture_output=True, text=True, cwd=cwd, timeout=300
    )


def swept_here_and_on_dask(python: Path, sweep: Path, out: Path) -> dict[str, list[dict]]:
    """The sweep file ``sweep`` run in that environment on a 2-worker Dask cluster and in
    one process, into folders under ``out``: each run's ``results.csv`` rows."""
    import csv

    tables = {}
    for name, extra in (("dask", ["--workers", "2"]), ("local", [])):
        folder = out / name
        done = glshade_in(python, "sweep", str(sweep), "--out", str(folder),
                          "--no-progress", *extra)  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        with open(folder / "results.csv", newline="") as fh:
            tables[name] = list(csv.DictReader(fh))
    return tables
