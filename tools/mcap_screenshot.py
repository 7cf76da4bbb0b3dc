"""docs/mcap-attitude.png: a run's run.mcap opened in a viewer. Foxglove's desktop app cannot be
installed on the machines the docs are made on, so the viewer is the rig's own: the file is read back
with Foxglove's ``mcap`` reader (not with anything of the writer's), its /attitude and /faults channels
are drawn with the reports' SVG plot (reports/svg_plot.py) and Debian's chromium takes the picture.
`make docs-images` runs it on the gyro-stuck run it makes; ``python tools/mcap_screenshot.py FILE``
draws any run.mcap."""

from __future__ import annotations

import html
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from rig.reports.svg_plot import plot  # noqa: E402
from tests.scenarios.test_library_and_reports import CHROMIUM_FLAGS  # noqa: E402

OUT = REPO / "docs" / "mcap-attitude.png"
DEFAULT = REPO / "build" / "docs-report" / "fault_gyro_stuck" / "run.mcap"


def page(path: Path) -> str:
    """The HTML page: the attitude channel's roll, pitch and yaw rate against their setpoints, the fault
    events shaded, each plot drawn from the MCAP's messages alone."""
    from mcap.reader import make_reader

    rows, faults = [], []
    with open(path, "rb") as f:
        reader = make_reader(f)
        for _, channel, message in reader.iter_messages(topics=["/attitude", "/faults"]):
            msg = json.loads(message.data)
            (rows if channel.topic == "/attitude" else faults).append((message.log_time, msg))
    t = np.array([ns / 1e9 for ns, _ in rows])

    def col(name: str) -> np.ndarray:
        return np.array([np.nan if m[name] is None else m[name] for _, m in rows], dtype=float)

    spans, start = [], None
    for ns, ev in faults:
        if ev["event"] == "active":
            start = ns / 1e9
        elif start is not None:
            spans.append((start, ns / 1e9))
            start = None
    marks = [("fault (/faults)", "#f4cccc", spans)] if spans else []
    svgs = [
        plot("roll", t, [("roll", col("roll"), ""), ("roll_sp", col("roll_sp"), "4 3"),
                         ("est_roll", col("est_roll"), "1 2")], "deg", marks),
        plot("pitch", t, [("pitch", col("pitch"), ""), ("pitch_sp", col("pitch_sp"), "4 3"),
                          ("est_pitch", col("est_pitch"), "1 2")], "deg", marks),
        plot("yaw rate", t, [("r", col("r"), ""), ("yaw_rate_sp", col("yaw_rate_sp"), "4 3")], "deg/s",
             marks),
    ]
    title = f"{path.parent.name}/run.mcap: /attitude ({len(rows)} messages) and /faults"
    return (f"<!doctype html><meta charset=utf-8><title>{html.escape(title)}</title>"
            f"<body style='font-family:sans-serif;margin:12px'><h3>{html.escape(title)}</h3>"
            "<p>read with Foxglove's mcap reader, drawn with the rig's own plot (reports/svg_plot.py)</p>"
            + "".join(f"<div>{s}</div>" for s in svgs) + "</body>")


def main() -> None:
    from playwright.sync_api import sync_playwright

    src = Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT
    with tempfile.TemporaryDirectory(prefix="rig-mcap-shot-") as tmp:
        html_file = Path(tmp) / "mcap.html"
        html_file.write_text(page(src))
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=CHROMIUM_FLAGS)
            pg = browser.new_page(viewport={"width": 800, "height": 700})
            pg.goto(html_file.as_uri())
            pg.screenshot(path=str(OUT), full_page=True)
            browser.close()
    print(OUT)


if __name__ == "__main__":
    main()
