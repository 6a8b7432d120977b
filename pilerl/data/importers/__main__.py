"""``python -m pilerl.data.importers --mapping m.yaml --dataset DIR LOG...``.

Imports the logs (all or nothing), stores the statistics and the provenance record, and
writes the data-quality report (``DIR/quality/import_<k>/report.md`` + one plot per
episode). Any bad input ends with ``error: <file>: <column>, <row>: <problem>`` and exit
status 1, and the dataset as it was (a new dataset is not created at all).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from pilerl.data.schema import SchemaError

from .dataset import import_to_dataset, quality_dir
from .mapping import load_mapping
from .quality import quality_report
from .readers import known_suffixes


def simulator_ranges(name: str) -> dict[str, tuple[float, float]]:
    """Sensor -> (low, high) as the simulator ``name`` declares them (its observation space)."""
    from pilerl.sim.registry import make_gym_env

    env = make_gym_env(name)
    try:
        return {
            k: (float(v.low.min()), float(v.high.max())) for k, v in env.observation_space.items()
        }
    finally:
        env.close()


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m pilerl.data.importers",
        description="Import machine logs into a pilerl dataset.",
    )
    parser.add_argument(
        "logs",
        nargs="+",
        type=Path,
        help=f"log files ({' '.join(known_suffixes())}) or ROS 2 bag folders",
    )
    parser.add_argument("--mapping", required=True, type=Path, help="mapping YAML")
    parser.add_argument(
        "--dataset",
        required=True,
        type=Path,
        help="dataset directory (created from the mapping when it does not exist)",
    )
    parser.add_argument("--description", default="", help="description of a new dataset")
    parser.add_argument(
        "--report", type=Path, help="quality report folder (default: DATASET/quality/import_<k>)"
    )
    parser.add_argument("--no-report", action="store_true", help="skip the quality report")
    parser.add_argument(
        "--controller-sensors",
        default="",
        help="comma-separated inputs of the controller to train (s and s'); "
        "each one the logs lack is warned about",
    )
    parser.add_argument(
        "--simulator", help="compare sensor ranges with this simulator's (e.g. pile_loader)"
    )
    args = parser.parse_args(argv)
    try:
        store, episodes, metas = import_to_dataset(
            args.logs, load_mapping(args.mapping), args.dataset, description=args.description
        )
    except (SchemaError, OSError) as error:  # LogImportError, MappingError: the message says where
        raise SystemExit(f"error: {error}") from None
    print(
        f"{args.dataset}: imported {len(metas)} episodes "
        f"({sum(m.n_samples for m in metas)} samples); {len(store)} in the dataset; "
        "statistics stored"
    )
    if args.no_report:
        return
    out = args.report or quality_dir(args.dataset)
    required = [s.strip() for s in args.controller_sensors.split(",") if s.strip()]
    reference = simulator_ranges(args.simulator) if args.simulator else None
    report = quality_report(
        episodes,
        out_dir=out,
        required_sensors=required,
        reference_ranges=reference,
        reference_name=f"simulator {args.simulator}" if args.simulator else "simulator",
        control_names=store.controls,
        sensor_units=store.sensors,
    )
    print(f"quality report: {report.path} ({len(report.warnings)} warning(s))")
    for warning in report.warnings:
        print(f"  warning: {warning}")


if __name__ == "__main__":
    main()
