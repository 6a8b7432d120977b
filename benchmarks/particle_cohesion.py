"""The particle soil's cohesion against Terzaghi's vertical cut, without the bucket.

Blocks of grains of a condition's material (default winter_c) are released from behind a
gate (``envs/pilerl_pile_loader/soil/particle_cut.py``) at heights that are multiples of
the critical height H_c = 4 c / (gamma g) tan(45 deg + phi / 2), and watched for
``--watch`` seconds. One process, one thread; every row is deterministic.

Columns: ``H/Hc`` the multiple asked, ``H m`` the block's height, ``grains``, ``G N`` each
grain's bond force, ``moved`` the share of grains that moved more than half a diameter,
``max cm`` the furthest any grain moved, ``drop cm`` how far the face column's top fell,
``cpu s``.

    python benchmarks/particle_cohesion.py
    python benchmarks/particle_cohesion.py --grain 0.08 --ratios 0.75 1 1.25
    python benchmarks/particle_cohesion.py --ratios 0.75 0.9 1 --watch 5
    python benchmarks/particle_cohesion.py --condition winter_c --loose   # c = 0
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

from pilerl_pile_loader.conditions import get_condition  # noqa: E402
from pilerl_pile_loader.soil.particle_cut import WATCH_S, critical_height_m, run_cut  # noqa: E402

DEFAULT_GRAIN_M = 0.1067  # the default pile's grains: 6 across the 0.64 m bucket mouth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--condition", default="winter_c", help="the material's preset")
    parser.add_argument("--grain", type=float, default=DEFAULT_GRAIN_M, help="diameter [m]")
    parser.add_argument(
        "--ratios", type=float, nargs="+", default=[0.5, 0.75, 1.0, 1.25, 1.5], help="H / H_c"
    )
    parser.add_argument("--watch", type=float, default=WATCH_S, help="seconds after release")
    parser.add_argument("--loose", action="store_true", help="c = 0 (heights from the real c)")
    args = parser.parse_args()
    m = get_condition(args.condition).material
    h_c = critical_height_m(m.cohesion_pa, m.friction_angle_deg, m.density_kg_m3)
    cohesion = 0.0 if args.loose else m.cohesion_pa
    print(
        f"{args.condition}: c {cohesion:g} Pa (H_c from {m.cohesion_pa:g} Pa), phi "
        f"{m.friction_angle_deg:g} deg, {m.density_kg_m3:g} kg/m^3: H_c {h_c:.3f} m; grains "
        f"{100 * args.grain:.2f} cm; watched {args.watch:g} s"
    )
    header = f"{'H/Hc':>5} {'H m':>5} {'grains':>6} {'G N':>6} {'moved':>5} {'max cm':>6} "
    header += f"{'drop cm':>7} {'cpu s':>5}"
    print(header)
    print("-" * len(header))
    for ratio in args.ratios:
        r = run_cut(
            ratio * h_c, cohesion, m.friction_angle_deg, m.density_kg_m3, args.grain, args.watch
        )
        print(
            f"{ratio:5.2f} {r.height_m:5.2f} {r.grains:6d} {r.bond_n:6.1f} {r.moved_fraction:5.2f} "
            f"{100 * r.max_displacement_m:6.1f} {100 * r.face_top_drop_m:7.1f} {r.cpu_s:5.1f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
