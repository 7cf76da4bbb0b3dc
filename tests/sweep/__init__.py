"""rig sweep's tests. SHOW is the issue's Show: 2 masses x 3 wind speeds x 4 seeds (24 runs)."""

SHOW = """
[sweep]
scenario = "hover_turbulence"
seeds = 4

[[sweep.vary]]
key = "vehicle.mass"
values = [1.1, 1.3]

[[sweep.vary]]
key = "environment.wind[0]"
values = [0.0, 2.0, 4.0]
"""
