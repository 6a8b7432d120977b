"""Curate recorded demonstrations into a training dataset (D_I or D_II) with statistics.

python recipes/build_dataset.py dataset=d_ii source=data/demos/summer
"""

from __future__ import annotations

import logging

from pilerl.config import register_configs
from pilerl.data import EpisodeStore, build_dataset
from pilerl.data.settings import BuildDatasetConfig
from pilerl.recipe import Run, recipe

log = logging.getLogger(__name__)
register_configs()


@recipe("build_dataset")
def main(config: BuildDatasetConfig, run: Run) -> dict[str, int]:
    source = EpisodeStore.open(config.source)
    run.begin(inputs={"source": config.source})
    rule = config.dataset
    dataset = build_dataset(
        source,
        config.out_dir,
        successful_only=rule.successful_only,
        rate_hz=rule.rate_hz,
        description=f"{rule.name} from {config.source}",
    )
    log.info("%s: %d episodes, %d samples", config.out_dir, len(dataset), dataset.n_samples)
    return {"episodes": len(dataset), "samples": dataset.n_samples}


if __name__ == "__main__":
    main()
