"""The README's table of Erleben's scenes, from the metrics.json files a
`taichi-dcd run all` wrote: settle time, final and maximum penetration depth, final
overlap, wall time per simulated second and the verdict (metrics.verdict).

Usage: python benchmarks/erleben_table.py [OUTPUTS]   (default: outputs)
"""

import json
import sys
from pathlib import Path

from common import machine_line

from taichi_dcd.scene.builtin import builtin_names
from taichi_dcd.measure.penetration import verdict


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "outputs")
    print(machine_line())
    print()
    print("| scene | settled (s) | final depth (m) | max depth (m) | final overlap (m³) | wall s / sim s "
          "| most substeps | verdict |")
    print("|---|---|---|---|---|---|---|---|")
    for name in builtin_names():
        path = root / name / "metrics.json"
        if not path.is_file():
            print(f"| {name} | no run in {root} | | | | | | |")
            continue
        m = json.loads(path.read_text())
        failed = verdict(m)
        settled = f"{m['time_to_settle']:.2f}" if m["settled"] else "no"
        if failed == "not settled":
            failed += f" ({m['final_max_vertex_speed']:.0e} m/s at {m['sim_time']:.0f} s)"
        print(f"| {name} | {settled} | {m['final_penetration_depth']:.1e} | {m['max_penetration_depth']:.1e} "
              f"| {m['final_overlap_volume']:.1e} | {m['wall_time_per_sim_second']:.2f} "
              f"| {m.get('most_substeps_in_a_frame', '')} | {'pass' if failed is None else 'FAIL: ' + failed} |")


if __name__ == "__main__":
    main()
