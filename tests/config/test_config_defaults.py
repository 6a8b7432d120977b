"""The YAML under conf/ states only what differs from the dataclasses' defaults.

Every default lives once, in the room's dataclass (checked in ``__post_init__``); a YAML
value equal to its schema's default is a second copy that can drift from the first. For
every primary config and every config group file backed by one of pilerl's schemas, each
value is compared with the schema's default at the same place. Two kinds of file are left
out: Hydra's own plugin groups (conf/hydra/: their schemas are the plugins') and the
``# @package _global_`` experiment overlays (they state what changes from a primary YAML).
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hydra.core.config_store import ConfigStore
from omegaconf import OmegaConf

from pilerl.config import register_configs

CONF = Path(__file__).resolve().parents[2] / "conf"
SKIPPED = ("hydra", "experiment")
PACKAGES = {"env": ("env", "env_schema")}  # ``# @package env`` files -> their schema

register_configs()


def schema_files() -> list[Path]:
    return sorted(
        path for path in CONF.rglob("*.yaml") if path.relative_to(CONF).parts[0] not in SKIPPED
    )


def schema_of(path: Path):
    """The structured default of the schema the file extends, or None."""
    text = path.read_text()
    package = next(
        (line.split()[-1] for line in text.splitlines() if line.startswith("# @package")), None
    )
    content = yaml.safe_load(text) or {}
    group = None if path.parent == CONF else path.parent.name
    if package in PACKAGES:
        group, name = PACKAGES[package]
    else:
        names = [d for d in content.get("defaults", []) if isinstance(d, str)]
        schemas = [d for d in names if d.split("@")[0].endswith("_schema")]
        if not schemas:
            return None
        name, _, placed = schemas[0].partition("@")  # ``pile_loader_schema@env``: env's
        group = placed or group
    repository = ConfigStore.instance().repo
    node = repository[group] if group else repository
    return OmegaConf.structured(node[f"{name}.yaml"].node)


def repeated_defaults(content, default, option: str, where: str = "") -> list[str]:
    """Keys of ``content`` whose value equals ``default``'s at the same place. A value equal
    to the option's own name (``backend: csv`` in logger/csv.yaml) is the choice the file
    makes, not a copy of a default, and is kept."""
    found = []
    for key, value in content.items():
        if key in ("defaults", "hydra") and not where:
            continue
        place = f"{where}{key}"
        if default is None or key not in default:
            continue
        if isinstance(value, dict) and OmegaConf.is_dict(default[key]) and value:
            found += repeated_defaults(value, default[key], option, f"{place}.")
            continue
        if isinstance(value, str) and "${" in value:
            continue
        known = OmegaConf.to_container(default, resolve=False)[key]
        if known == "???" or value == option:
            continue
        if value == known:
            found.append(f"{place}: {value!r}")
    return found


FILES = [p for p in schema_files() if schema_of(p) is not None]


def test_the_schema_backed_files_are_the_ones_expected():
    """Every primary config and group file outside conf/hydra and conf/experiment."""
    assert sorted(map(str, set(schema_files()) - set(FILES))) == []
    assert len(FILES) >= 30


@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(CONF)) for p in FILES])
def test_no_value_repeats_its_schema_default(path):
    content = yaml.safe_load(path.read_text()) or {}
    repeated = repeated_defaults(content, schema_of(path), option=path.stem)
    assert not repeated, f"{path.relative_to(CONF)} restates defaults: {repeated}"


def test_the_check_sees_a_restated_default():
    default = OmegaConf.structured(ConfigStore.instance().repo["algorithm"]["ppo_schema.yaml"].node)
    assert repeated_defaults({"epochs": 4, "gamma": 0.9}, default, option="ppo") == ["epochs: 4"]
    assert repeated_defaults({"name": "ppo"}, default, option="ppo") == []


PRIMARY = sorted(p.stem for p in CONF.glob("*.yaml"))
RUN_NAMED_BY = {"train_bc": "dannet_", "finetune": "ppo_"}  # the policy / the algorithm


@pytest.mark.parametrize("name", PRIMARY)
def test_every_recipe_shares_the_run_directory_layout(name):
    """One hydra/output choice names every recipe's run and sweep directories."""
    from hydra import compose, initialize_config_dir

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3", job_name=name):
        cfg = compose(config_name=name, return_hydra_config=True)
    assert cfg.hydra.run.dir.startswith(f"outputs/{name}/{RUN_NAMED_BY.get(name, '')}20")
    assert cfg.hydra.sweep.dir.startswith(f"multirun/{name}/20")
    assert "hydra/output: pilerl" in (CONF / f"{name}.yaml").read_text()
