"""A plugin written from docs/simulator_plugins.md alone works in every recipe.

The document's file blocks (the package ``my_heater``) are written into a temporary
directory and installed there with pip (``--target``: no other test sees the plugin);
then the document's recipe commands run on it by name, in this process, on the docs
test's tiny budgets.
"""

from __future__ import annotations

import json
import runpy
import subprocess
import sys

import pytest
from test_docs_commands import ROOT, TINY, document_steps

from pilerl.sim import registry, settings

DOCUMENT = ROOT / "docs" / "simulator_plugins.md"


@pytest.fixture(scope="module")
def installed_plugin(tmp_path_factory):
    """The document's package installed into ``<tmp>/site``, on ``sys.path`` (installed
    once for this module's tests; the working directory is the temporary directory)."""
    tmp_path = tmp_path_factory.mktemp("plugin")
    for step in document_steps(DOCUMENT):
        if step.writes is not None:
            path = tmp_path / step.writes
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(step.text)
    site = tmp_path / "site"
    subprocess.run(
        [
            sys.executable,
            *("-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation"),
            *("--no-index", "--target", str(site), str(tmp_path / "my_heater")),
        ],
        check=True,
        timeout=300,
    )
    with pytest.MonkeyPatch.context() as monkeypatch:
        monkeypatch.syspath_prepend(str(site))
        monkeypatch.chdir(tmp_path)
        monkeypatch.setenv("OMP_NUM_THREADS", "1")
        registry.refresh_simulators()
        yield tmp_path
    registry.refresh_simulators()
    settings.settings_class.cache_clear()
    for name in [m for m in sys.modules if m == "my_heater" or m.startswith("my_heater.")]:
        del sys.modules[name]


def run_recipe(command: str) -> None:
    argv = command.split()[1:]  # without "python"
    recipe = ROOT / argv[0]
    old_argv = sys.argv
    sys.argv = [str(recipe), *argv[1:], *TINY[recipe.name]]
    try:
        runpy.run_path(str(recipe), run_name="__main__")
    except SystemExit as exit_:
        assert exit_.code in (0, None), f"{command}: exit code {exit_.code}"
    finally:
        sys.argv = old_argv


def test_the_documented_plugin_runs_in_every_recipe_by_name(installed_plugin):
    assert "my_heater" in registry.available_simulators()
    commands = [
        step.text
        for step in document_steps(DOCUMENT)
        if step.writes is None and step.text.startswith("python recipes/") and "heater" in step.text
    ]
    recipes = [command.split()[1] for command in commands]
    assert recipes == [
        f"recipes/{name}.py"
        for name in ("record", "build_dataset", "train_bc", "evaluate", "finetune")
    ]
    for command in commands:
        run_recipe(command)
    demos = json.loads((installed_plugin / "data/demos/heater/index.json").read_text())
    assert demos["sensors"] == {"temperature": "degC", "heater_power": "kW"}
    assert demos["controls"] == ["heater"] and len(demos["episodes"]) == 2
    assert (installed_plugin / "outputs/bc/heater/best.pt").is_file()
    evaluated = sorted(installed_plugin.glob("outputs/evaluate/*/summary.json"))
    summary = json.loads(evaluated[-1].read_text())
    assert {"mild", "frost"} <= set(summary)  # every declared condition
    assert all(set(row["failure_modes"]) == {"too_cold", "too_hot"} for row in summary.values())
    episodes = evaluated[-1].with_name("episodes.csv").read_text().splitlines()
    assert episodes[0].endswith("final_error_degc,failure_mode")  # the plugin's columns
    finetuned = sorted(installed_plugin.glob("outputs/finetune/*/results.json"))
    results = json.loads(finetuned[-1].read_text())
    assert set(results["before"]) == {"winter", "mild"}  # declared groups + ungrouped


def test_an_option_the_plugin_does_not_declare_is_refused_with_the_list(installed_plugin):
    config = settings.settings_class("my_heater")()
    with pytest.raises(ValueError, match=r"has no option\(s\) \['soil'\].*'control_hz'"):
        config.make_kwargs(soil="particles")
