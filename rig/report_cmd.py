"""``rig report DIR [--pdf] [--operator NAME]``: the reports of a finished ``rig run`` made again from
what it wrote (each run's result.json, telemetry.csv and the DUT's stderr): the suite's index.html and,
with ``--pdf``, the acceptance report DIR/acceptance.pdf (and its source, acceptance.html). The
scenario files need not exist any more: their names and hashes are in the results. A folder a
``rig run`` is still writing is refused. Exit status: 0 written, 2 bad usage or not a report folder,
3 the PDF could not be printed."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from rig.run_cmd import EXIT_ERROR, EXIT_USAGE, ReportFolder, UsageError, add_pdf_options, write_acceptance


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="write a finished run's index page again and, with --pdf, its acceptance PDF",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("dir", type=Path, metavar="DIR", help="the --out folder of a rig run")
    add_pdf_options(p)


def main(args: argparse.Namespace) -> int:
    from reports import html_report
    from reports.load import NotAReportFolder, read_folder
    from reports.pdf import PdfError, chromium

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
