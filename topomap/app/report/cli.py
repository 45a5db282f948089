"""Rebuild a sweep's report from its folder, at any time: ``python -m topomap.app.report
SWEEP_DIR [--metric M] [--no-figure]`` (e.g. for another metric, or after an interrupted
sweep)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..results import METRICS
from .summary import print_report, write_report

__all__ = ["main"]


def main(argv=None) -> int:
    """``python -m topomap.app.report SWEEP_DIR [--metric M] [--no-figure]``: rebuild a sweep report."""
    parser = argparse.ArgumentParser(prog="python -m topomap.app.report", description=main.__doc__)
    parser.add_argument("sweep_dir", type=Path)
    parser.add_argument("--metric", default="ari", choices=list(METRICS))
    parser.add_argument("--no-figure", dest="figure", action="store_false")
    args = parser.parse_args(argv)
    if not args.sweep_dir.is_dir():
        parser.error(f"{args.sweep_dir} is not a folder")
    report = write_report(args.sweep_dir, metric=args.metric, figure=args.figure)
    if not report.rows:
        print(f"topomap: error: no job folders (holding .hydra/) under {args.sweep_dir}",
              file=sys.stderr)
        return 1
    print_report(report)
    return 0
