"""Curate recorded demonstrations into a training dataset (D_I or D_II) with statistics.

python recipes/build_dataset.py dataset=d_ii source=data/demos/summer
"""

from __future__ import annotations

import logging

import hydra
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf

from pilerl.config import register_configs
from pilerl.data import EpisodeStore, build_dataset
from pilerl.data.settings import BuildDatasetConfig
from pilerl.runs import begin_run, finish_run
from pilerl.runtime import limit_threads

log = logging.getLogger(__name__)
register_configs()


@hydra.main(config_path="../conf", config_name="build_dataset", version_base="1.3")
def main(cfg: DictConfig) -> None:
    limit_threads()
    config: BuildDatasetConfig = OmegaConf.to_object(cfg)
    source = EpisodeStore.open(config.source)
    run_dir = HydraConfig.get().runtime.output_dir
    settings = OmegaConf.to_container(cfg, resolve=True)
    if begin_run(run_dir, settings, inputs={"source": config.source}):
        log.info("%s already finished: skipping (same settings)", run_dir)
        return
    rule = config.dataset
    dataset = build_dataset(
        source,
        config.out_dir,
        successful_only=rule.successful_only,
        rate_hz=rule.rate_hz,
        description=f"{rule.name} from {config.source}",
    )
    log.info("%s: %d episodes, %d samples", config.out_dir, len(dataset), dataset.n_samples)
    finish_run(run_dir, {"episodes": len(dataset), "samples": dataset.n_samples})


if __name__ == "__main__":
    main()
