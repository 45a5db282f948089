"""Install topomap as a user does -- from a built wheel into a fresh virtual environment -- and run
it from a folder outside the checkout.

    python tests/install_check.py [--keep]

Builds the wheel (``pip wheel --no-deps``), makes a new venv in a temporary folder, installs
``<wheel>[arena]`` and the plugin ``plugins/topomap-gtest`` (an entry point of group
``topomap``), then from another temporary folder: imports every module of the installed package,
runs ``python -c "from topomap import MapLearner"``, a robot's odometry read from its scans
(:data:`ROBOT_SCANS`), ``topomap`` (the paper's experiment),
``topomap experiment=arena_two_rooms``, ``topomap --list-plugins`` (the plugin's split criterion
must be listed) and ``topomap --cfg job experiment=<each preset>`` (every packaged config is
found).  Exits 1 naming the first step that failed.  ``.ci/run`` runs it after the test suite.
"""

from __future__ import annotations

import argparse
import glob
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: imports every module of the installed package (but the ``__main__`` ones, which run the
#: command); a module whose optional library is not installed must fail only with that
#: library's ImportError
IMPORT_ALL = r"""
import importlib, pkgutil, sys, topomap
assert "site-packages" in topomap.__file__, topomap.__file__
failed, names = [], [m.name for m in pkgutil.walk_packages(topomap.__path__, "topomap.")
                     if not m.name.endswith(".__main__")]
for name in names:
    try:
        importlib.import_module(name)
    except ImportError as exc:
        if exc.name is None or exc.name.split(".")[0] in ("topomap",):
            failed.append(f"{name}: {exc}")
    except Exception as exc:
        failed.append(f"{name}: {type(exc).__name__}: {exc}")
print(f"imported {len(names)} modules")
sys.exit("\n".join(failed) if failed else 0)
"""


def step(title: str, cmd: list[str], cwd: Path, env: dict, expect: str | None = None) -> None:
    print(f"-- {title}: {' '.join(cmd)}", flush=True)
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    if proc.returncode != 0 or (expect is not None and expect not in proc.stdout):
        sys.stdout.write(proc.stdout[-3000:])
        sys.stderr.write(proc.stderr[-3000:])
        why = f"exit {proc.returncode}" if proc.returncode else f"{expect!r} not in its output"
        raise SystemExit(f"install check failed at '{title}': {why}")


#: a robot's odometry read from its egocentric scans (compiled ICP calling LAPACK by name): 30
#: steps of 1 cm, turning 0.02 rad a step, in a 2 x 1.5 m room; the poses within 3 cm of the truth
ROBOT_SCANS = r"""
import numpy as np
from topomap.core.motion.registration import scan_odometry
def scan(x, y, th, B=60):
    a = th + 2 * np.pi * np.arange(B) / B
    c, s = np.cos(a), np.sin(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(c > 0, (2.0 - x) / c, np.where(c < 0, -x / c, np.inf))
        ty = np.where(s > 0, (1.5 - y) / s, np.where(s < 0, -y / s, np.inf))
    return np.minimum(tx, ty)
truth = [np.array([0.6, 0.5, 0.1])]
for _ in range(30):
    x, y, th = truth[-1]
    truth.append(np.array([x + 0.01 * np.cos(th), y + 0.01 * np.sin(th), th + 0.02]))
poses = scan_odometry(np.array([scan(*p) for p in truth]))
moved = poses[-1, :2] - poses[0, :2]
true = truth[-1][:2] - truth[0][:2]
c, s = np.cos(-truth[0][2]), np.sin(-truth[0][2])
assert np.hypot(*(moved - [c * true[0] - s * true[1], s * true[0] + c * true[1]])) < 0.03, poses[-1]
print("scans read:", np.round(poses[-1], 3))
"""

def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", action="store_true", help="keep the temporary folders")
    args = parser.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="topomap-install-"))
    try:
        wheels, venv, work = tmp / "wheels", tmp / "venv", tmp / "elsewhere"
        work.mkdir()
        env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
        step("build the wheel", [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w",
                                 str(wheels), str(ROOT)], tmp, env)
        (wheel,) = glob.glob(str(wheels / "topomap-*.whl"))
        step("a fresh venv", [sys.executable, "-m", "venv", str(venv)], tmp, env)
        bindir = venv / ("Scripts" if os.name == "nt" else "bin")
        py = str(bindir / "python")
        env["PATH"] = f"{bindir}{os.pathsep}{env.get('PATH', '')}"
        step("install the wheel", [py, "-m", "pip", "install", "-q", f"{wheel}[arena]"], tmp, env)
        step("install a plugin", [py, "-m", "pip", "install", "-q", "--no-deps",
                                  str(ROOT / "plugins" / "topomap-gtest")], tmp, env)
        step("import every module", [py, "-c", IMPORT_ALL], work, env)
        step("import the learner", [py, "-c", "from topomap import MapLearner"], work, env)
        step("a robot's scans read", [py, "-c", ROBOT_SCANS], work, env)
        step("the paper's experiment", ["topomap", "output.progress=false"], work, env)
        step("a continuous world", ["topomap", "experiment=arena_two_rooms",
                                    "output.progress=false", "output.figures=false"], work, env)
        step("the plugin's entry point", ["topomap", "--list-plugins"], work, env,
             expect="G-test between the two halves")
        for preset in sorted(p.stem for p in (ROOT / "conf" / "experiment").glob("*.yaml")):
            step(f"the preset {preset}", ["topomap", "--cfg", "job", f"experiment={preset}"],
                 work, env)
        if not list((work / "outputs" / "runs").glob("*/*/map.json")):
            raise SystemExit("install check failed: no map.json under outputs/runs/ of the folder")
        print(f"install check passed ({wheel.rsplit('/', 1)[-1]})")
        return 0
    finally:
        if args.keep:
            print(f"kept {tmp}")
        else:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
