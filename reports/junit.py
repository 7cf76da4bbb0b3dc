"""JUnit XML for CI: one testsuite per scenario run, one testcase per criterion; a run that ended in
error is one errored testcase naming the reason (CI systems show it as broken, not as failed)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence

from rig.reports.values import bus_problems_text, fmt_limits, fmt_margin, fmt_value, mode_text
from rig.scenarios.result import RunResult


def render(results: Sequence[RunResult]) -> str:
    root = ET.Element("testsuites", name="rig")
    for r in results:
        failures = sum(m.outcome == "fail" for m in r.measurements)
        suite = ET.SubElement(
            root,
            "testsuite",
            name=r.scenario.stem,
            tests=str(len(r.measurements) or 1),
            failures=str(failures if r.verdict not in ("error", "interrupted") else 0),
            errors=str(int(r.verdict in ("error", "interrupted"))),
            time=f"{float(r.metadata.get('wall_time') or 0.0):.3f}",
            # (JUnit's schema: the local form without a zone; the rig's times are UTC)
            timestamp=str(r.metadata.get("started") or "").removesuffix("+00:00"),
            hostname=str(r.metadata.get("host") or ""),
        )
        props = ET.SubElement(suite, "properties")
        for k in ("seed", "scenario_file", "scenario_sha256", "airframe", "airframe_sha256", "started",
                  "host", "dut_command", "dut_firmware", "dut_firmware_sha256", "dut_program",
                  "dut_program_sha256", "plant_fmu_sha256", "rig_version"):
            ET.SubElement(props, "property", name=k, value=str(r.metadata.get(k)))
        ET.SubElement(props, "property", name="mode", value=mode_text(r.metadata))
        if "bus_problems" in r.metadata:  # (the MCU tier: what the firmware saw go wrong on its bus)
            ET.SubElement(props, "property", name="bus_problems",
                          value=bus_problems_text(r.metadata["bus_problems"]))
        if r.verdict in ("error", "interrupted"):
            case = ET.SubElement(suite, "testcase", classname=r.scenario.stem, name="run")
            ET.SubElement(case, "error", message=r.error or "error").text = r.stderr[-4000:]
            continue
        for m in r.measurements:
            case = ET.SubElement(suite, "testcase", classname=r.scenario.stem, name=m.name)
            text = (f"{m.metric} of {m.signal} = {fmt_value(m.value, m.units)}; limits {fmt_limits(m)}; "
                    f"margin {fmt_margin(m)}")
            if m.marginal:
                props = ET.SubElement(case, "properties")
                ET.SubElement(props, "property", name="marginal", value="true")
            if m.outcome == "fail":
                ET.SubElement(case, "failure", message=f"{text} ({m.reason})")
            else:
                ET.SubElement(case, "system-out").text = text
    ET.indent(root)
    return ET.tostring(root, encoding="unicode", xml_declaration=True) + "\n"
