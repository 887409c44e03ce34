"""Robust vs plain HGAD under faults: 200 paired random missions per preset (issue 15).

Run: python benchmarks/bench_resilience.py [MISSIONS] (SKYMULE_BENCH_TINY=1: 4 missions)

Mission m of a preset uses seed ``preset.seed + m`` and buffers drawn from it (uniform in
[0.5, 1.5] x the preset's, :func:`skymule.resilience.leveled`). Two conditions on the same
missions: fault-free, and faulty = one random outage per tower (exponential length, mean 60 s)
plus an SNR error of 6 dB std (3 s correlation) on what the policy sees. Prints per policy the
mean downloaded Mbit with its 95 % CI, and the paired difference robust - plain (mean, 95 % CI).
"""

from __future__ import annotations

import sys
from pathlib import Path

from _sizes import size

from skymule.resilience import paired_difference, run_study, table
from skymule.scenario import Scenario, load_scenario, scenario_from_dict

PRESETS = ("paper-sim-fixed", "paper-sim-autonomous")
POLICIES = ("hgad", "hgad-robust")
FAULTS = [
    {"kind": "outage", "params": {"mean_duration_s": 60.0}},
    {"kind": "snr-error", "params": {"std_db": 6.0, "correlation_s": 3.0}},
]


def faulty(base: Scenario) -> Scenario:
    data = base.to_toml_dict()
    data["faults"] = FAULTS
    return scenario_from_dict(data, f"{base.name} + faults", Path(base.base_dir))


def main() -> None:
    missions = int(sys.argv[1]) if len(sys.argv) > 1 else size(200, 4)
    for preset in PRESETS:
        base = load_scenario(preset)
        for label, scenario in (("fault-free", base), ("outages + 6 dB SNR error", faulty(base))):
            study = run_study(scenario, "outage", [0.0], POLICIES, missions, with_bound=False)
            print(f"{preset}, {label}, {missions} missions:")
            for row in table(study).itertuples():
                print(f"  {row.policy:12s} {row.mbit_mean:9.1f} +- {row.mbit_ci95:6.1f} Mbit")
            mean, half = paired_difference(study, "hgad-robust", "hgad", 0.0)
            plain = float(study.rows[study.rows["policy"] == "hgad"]["mbit"].mean())
            print(
                f"  robust - plain: {mean:+.1f} +- {half:.1f} Mbit "
                f"({100 * mean / plain:+.2f} % of plain)"
            )


if __name__ == "__main__":
    main()
