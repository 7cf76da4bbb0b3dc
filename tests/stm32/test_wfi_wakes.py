"""Virtual time across the core's sleeps (tests/stm32/firmware/wfi_wakes.c): under icount with sleep=off,
QEMU moves virtual time on to the next timer's deadline while the core sleeps in WFI. QEMU 7.2 could do
that from its main loop with a clock behind the core by the instructions it ran just before WFI (counted
only after the core's run returns), and so wake it late by them, by how the host scheduled its threads;
the engine carries qemu/patches/icount-warp-in-vcpu.patch, which leaves the warp to the vCPU thread.
Here 2000 wake-ups, each after a handler of another length, must each come at the same distance from
its timer's update event, in runs side by side."""

from __future__ import annotations

import subprocess

from tests.stm32.conftest import RUN_TIMEOUT_S, engine_or_skip, firmware, reports, run_command

WAKES = 2000


def test_every_wake_from_wfi_is_at_its_update_event_in_each_of_two_runs_side_by_side() -> None:
    cmd = run_command(engine_or_skip(), firmware("wfi_wakes"))
    runs = [subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True) for _ in range(2)]
    try:
        outputs = [run.communicate(timeout=RUN_TIMEOUT_S) for run in runs]
    finally:
        for run in runs:
            run.kill()
            run.wait()
    assert [run.returncode for run in runs] == [0, 0], outputs
    first, second = (reports(out) for out, _ in outputs)
    assert first["wakes"] == WAKES
    assert first["late_min"] == first["late_max"], first  # (the handler's first read, cycles after the event)
    assert first == second
