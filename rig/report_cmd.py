"""``rig report DIR [--pdf] [--mcap] [--operator NAME]``: the reports of a finished ``rig run`` made
again from what it wrote (each run's result.json, telemetry.csv and the DUT's stderr): the suite's
index.html; with ``--pdf``, the acceptance report DIR/acceptance.pdf (and its source, acceptance.html);
with ``--mcap``, each run's run.mcap (for runs made before the rig wrote it: their I2C transfers and
RC frames were not kept, and the file's metadata says so). The
scenario files need not exist any more: their names and hashes are in the results. A folder a
``rig run`` is still writing is refused. Exit status: 0 written, 2 bad usage or not a report folder,
3 the PDF could not be printed."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rig.run_cmd import EXIT_ERROR, EXIT_USAGE, ReportFolder, UsageError, add_pdf_options, write_acceptance

#: why an old run's run.mcap lacks these channels
OLD_RUN = {
    "/i2c": "written afterwards by rig report --mcap from result.json and telemetry.csv: the run's I2C "
            "transfers were not kept (result.json's bus_transactions counts them)",
    "/sensors": "decoded from /i2c, which is empty",
    "/rc": "written afterwards by rig report --mcap: the RC frames sent were not kept (the sticks are "
           "on /attitude as roll_sp, pitch_sp, yaw_rate_sp and throttle)",
}


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="write a finished run's index page again and, with --pdf, its acceptance PDF",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dir", type=Path, metavar="DIR", help="the --out folder of a rig run")
    add_pdf_options(p)
    p.add_argument("--mcap", action="store_true",
                   help="also write each run's DIR/<scenario>/run.mcap from its result.json and "
                   "telemetry.csv")


def main(args: argparse.Namespace) -> int:
    from rig.reports import html_report
    from rig.reports.load import NotAReportFolder, read_folder
    from rig.reports.pdf import PdfError, chromium

    out: Path = args.dir
    try:
        if not out.is_dir():
            raise UsageError(f"{out}: no such folder")
        if args.pdf and chromium() is None:
            raise UsageError(
                "--pdf: no chromium on PATH to print the PDF with (Debian: apt-get install chromium)"
            )
        with ReportFolder(out):
            try:
                results, not_run = read_folder(out)
            except (NotAReportFolder, ValueError, KeyError) as e:
                raise UsageError(str(e)) from None
            links = [("junit.xml", "JUnit XML for CI")]
            code = 0
            if args.mcap:
                from rig.reports import mcap

                for r in results:
                    path = mcap.write_run(out / r.scenario.stem, r, OLD_RUN)
                    print(f"run.mcap: {path} ({path.stat().st_size // 1024} KiB)", file=sys.stderr)
            if args.pdf:
                t0 = time.perf_counter()
                try:
                    pdf = write_acceptance(out, results, not_run, args.operator)
                    links.insert(0, ("acceptance.pdf", "the acceptance report (PDF)"))
                    print(
                        f"acceptance report: {pdf} ({pdf.stat().st_size // 1024} KiB, "
                        f"{time.perf_counter() - t0:.1f} s)",
                        file=sys.stderr,
                    )
                except PdfError as e:
                    print(f"rig report: error: {e}", file=sys.stderr)
                    code = EXIT_ERROR
            (out / "index.html").write_text(
                html_report.render_index(
                    results, [f"{r.scenario.stem}/report.html" for r in results], not_run, links
                )
            )
            return code
    except UsageError as e:
        for line in str(e).splitlines():
            print(f"rig report: {line}", file=sys.stderr)
        return EXIT_USAGE
