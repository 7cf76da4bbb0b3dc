"""HTML to PDF with Debian's headless Chromium (``chromium --print-to-pdf``).

Why Chromium and not a PDF library: the acceptance PDF is the same HTML and inline SVG as the other
reports, so one renderer draws both and a page looks the same on screen and on paper; Chromium renders
SVG and CSS paged media (page breaks, running page numbers in ``@page`` margin boxes) completely, where
WeasyPrint or ReportLab would mean a second layout of every table and plot; and the test of report.html
drives the same browser. It runs with a throw-away profile and without network, sync or updates."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

#: The browser, found on PATH (Debian's package installs /usr/bin/chromium); RIG_CHROMIUM overrides it
CHROMIUM_NAMES = ("chromium", "chromium-browser")
FLAGS = (
    "--headless",
    "--no-sandbox",  # (root in a container has no user namespace for the sandbox)
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)


#: the longest TMPDIR under which Chromium's socket path still fits (a longer one: /tmp instead)
MAX_BASE = 48


class PdfError(RuntimeError):
    pass


def chromium() -> str | None:
    """The Chromium executable, or None when there is none."""
    given = os.environ.get("RIG_CHROMIUM")
    if given:
        return given if shutil.which(given) else None
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


def html_to_pdf(html_file: Path, pdf_file: Path, timeout: float = 180.0) -> None:
    """Prints ``html_file`` (with everything it needs inline) to ``pdf_file``; raises PdfError with
    Chromium's own words when it cannot."""
    exe = chromium()
    if exe is None:
        raise PdfError("no chromium on PATH (Debian: apt-get install chromium)")
    pdf_file.unlink(missing_ok=True)
    # Chromium puts its singleton socket in $TMPDIR/org.chromium.Chromium.XXXXXX/: under a long TMPDIR
    # that path passes the 107 bytes a socket's path may have and Chromium aborts. So it gets a short
    # private TMPDIR of its own (its profile inside), removed afterwards with whatever it left there.
    base = tempfile.gettempdir()
    base = base if len(base) <= MAX_BASE else "/tmp"
    with tempfile.TemporaryDirectory(prefix="rig-chromium-", dir=base) as work:
        cmd = [
            exe,
            *FLAGS,
            f"--user-data-dir={work}/profile",
            "--no-pdf-header-footer",
            f"--print-to-pdf={pdf_file.resolve()}",
            html_file.resolve().as_uri(),
        ]
        try:
            done = subprocess.run(
                cmd,
                capture_output=True,
                text=True,
                timeout=timeout,
                stdin=subprocess.DEVNULL,
                env={**os.environ, "TMPDIR": work},
            )
        except subprocess.TimeoutExpired:
            raise PdfError(f"chromium did not finish the PDF in {timeout:g} s") from None
    if done.returncode != 0 or not pdf_file.is_file() or pdf_file.stat().st_size == 0:
        said = " | ".join(line for line in done.stderr.splitlines()[-5:] if line.strip())
        raise PdfError(f"chromium could not print {html_file} (status {done.returncode}): {said}")
