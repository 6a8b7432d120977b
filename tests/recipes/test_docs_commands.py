"""Every command in README.md and docs/*.md runs as written (on tiny budgets).

The shell blocks of each document are read in order and run in one fresh working
directory per document, so a command may use what an earlier command of the same
document wrote (demonstrations, datasets, checkpoints). A block whose info string names a
file (```yaml file=mapping.yaml) is written to that file when it is reached, so a
walk-through's mapping or script is the one its commands use. Recipes and ``python -m``
modules run in this process (imports are paid once); budgets are cut through overrides
(``TINY``), which only shrink episodes, steps, frames and an Optuna sweep's trials.
Documents that begin with the same commands (README, experiments, training and
fine-tuning all record demonstrations first) run them once per session: a later
document starts from a copy of the working directory those commands left
(``SharedPrefixes``); a command two documents run on the same recorded data runs in one
of them (``RUN_ELSEWHERE``), and multiruns use Hydra's in-process launcher instead of
worker processes (``IN_PROCESS_LAUNCHERS``: their own tests start those). A command that
cannot run here says why in ``NOT_RUN``: the
README's two front-door commands (CI runs them as written), a Ray cluster's commands,
and commands over a user's own files. Every other command must
run and exit 0, so the documents cannot drift from the code.
"""

from __future__ import annotations

import re
import runpy
import shlex
import shutil
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
# a fenced block: its info string (```bash, ```python file=make_log.py) and its text
FENCE = re.compile(r"^[ \t]*```([^\n`]*)\n(.*?)^[ \t]*```", re.S | re.M)
SHELLS = ("bash", "sh", "shell")

# overrides appended to each recipe's command: tiny budgets, one worker process
TINY = {
    "record.py": ["n_episodes=2", "record_hz=20", "workers=1"],
    "build_dataset.py": [],
    "train_bc.py": [
        "seed=0",  # one training seed: the paper's overlays sweep seed=0,1,2
        "gradient_steps=4",
        "epochs=1",
        "evaluation.episodes=1",  # left out for ensembles, which evaluate nothing
        "evaluation.workers=1",
        "evaluation.videos=false",
    ],
    "evaluate.py": ["evaluation.episodes=1", "evaluation.workers=1", "evaluation.videos=false"],
    "finetune.py": [
        "time_budget_minutes=0.02",
        "algorithm.frames_per_batch=128",
        "algorithm.minibatch_size=64",
        "collection.envs_per_worker=2",
        "evaluation.every_frames=0",
        "evaluation.final_episodes=1",
        "evaluation.workers=1",
        "checkpoint_every_frames=128",
    ],
    "scoop.py": ["video=false", "env.start_distance_range_m=[1.0,1.0]"],
    "pipeline.py": [],
    "deploy.py": ["hil.episodes=1"],
}
# trials of a documented Optuna sweep (tests/training/test_training.py's search runs 3)
TINY_OPTUNA_TRIALS = 3
# options appended to a ``python -m`` module's command (argparse: the last one counts)
TINY_MODULES = {"pilerl.deploy faults": ["--cases", "1"]}
PLUGIN_TEST = (
    "tests/sim/test_third_party_plugin.py installs the documented plugin into a temporary "
    "directory and runs these commands on it"
)
CROSS_SOIL = (
    "evaluates Exp. 3's 18 checkpoints (three training seeds; this test trains seed 0): "
    "about 20 minutes on the heightfield, an hour on the particle soil; "
    "tests/reports/test_seeds_and_soils.py builds its report section"
)
# process launchers this test swaps for Hydra's in-process one: starting worker processes
# (and their imports) cost more than the tiny jobs. The launcher configs themselves are run
# by the test named beside each one.
IN_PROCESS_LAUNCHERS = {
    "hydra/launcher=local_parallel": "tests/sweeps/test_sweeps.py::"
    "test_multirun_with_the_local_parallel_launcher_then_summary",
    "hydra/launcher=ray_local": "tests/rl/test_ray.py::"
    "test_multirun_on_the_ray_launcher_runs_each_job_with_its_overrides",
}
# (document, command prefix) -> the step of another document that runs the same command on
# the same inputs, so this document's copy is not run twice
RUN_ELSEWHERE = {
    ("README.md", "python recipes/train_bc.py --multirun +experiment=exp3_attention"): (
        "docs/experiments.md",
        "python recipes/train_bc.py --multirun +experiment=exp3_attention",
    ),
}
# command prefix -> why it is not run by this test
NOT_RUN = {
    "bash scripts/setup.sh": "the README's front door: CI (.ci/run) runs both as written",
    "ray ": "needs a Ray cluster",
    "python recipes/record.py --multirun hydra/launcher=ray_cluster": "needs a Ray cluster",
    "python recipes/train_bc.py --multirun hydra/launcher=ray_cluster": "needs a Ray cluster",
    "python -m pilerl.deploy runtime": "serves until a machine connects (a second terminal); "
    "tests/deploy/test_deploy_runtime.py runs it against a bridge",
    "python -m pilerl.deploy bridge": "the second terminal of the runtime above",
    "python -m pilerl.deploy rearm": (
        "talks to a running runtime (tests/deploy/test_deploy_runtime.py)"
    ),
    "python recipes/evaluate.py --multirun env.soil=heightfield checkpoint=multirun/": CROSS_SOIL,
    "python recipes/evaluate.py --multirun env.soil=particles checkpoint=multirun/": CROSS_SOIL,
    "python -m pilerl.reports.paper --cross-soil": CROSS_SOIL,
    "pip install -e ./my_heater": PLUGIN_TEST,
    'python -c "from pilerl.sim import available_simulators': PLUGIN_TEST,
    "python recipes/record.py env=my_heater": PLUGIN_TEST,
    "python recipes/build_dataset.py dataset=d_i source=data/demos/heater": PLUGIN_TEST,
    "python recipes/train_bc.py env=my_heater": PLUGIN_TEST,
    "python recipes/evaluate.py env=my_heater": PLUGIN_TEST,
    "python recipes/finetune.py env=my_heater": PLUGIN_TEST,
    "python recipes/deploy.py controller=outputs/deploy_try/nnetv2.onnx env.control_hz=3": (
        "serves until a machine connects; the mode=hil commands run the same runtime"
    ),
}


@dataclass(frozen=True)
class Command:
    document: Path
    line: int
    text: str
    writes: str | None = None  # a file block: the file's name (``text`` is its content)

    @property
    def argv(self) -> list[str]:
        words = shlex.split(self.text, comments=True)
        if words and words[0].endswith("python"):
            words = words[1:]
        return words

    def __str__(self) -> str:
        where = f"{self.document.relative_to(ROOT)}:{self.line}"
        return f"{where}: file {self.writes}" if self.writes else f"{where}: {self.text}"


def document_steps(document: Path) -> list[Command]:
    """The document's commands and file blocks in reading order (continuations joined)."""
    text = document.read_text()
    steps = []
    for fence in FENCE.finditer(text):
        info, body = fence.group(1).split(), fence.group(2)
        first_line = text[: fence.start(2)].count("\n") + 1
        named = [word.removeprefix("file=") for word in info if word.startswith("file=")]
        if named:
            indent = len(body) - len(body.lstrip(" "))
            content = "\n".join(line[indent:] for line in body.splitlines()) + "\n"
            steps.append(Command(document, first_line, content, writes=named[0]))
            continue
        if not info or info[0] not in SHELLS:
            continue
        lines = body.splitlines()
        i = 0
        while i < len(lines):
            start, command = i, lines[i]
            while command.rstrip().endswith("\\") and i + 1 < len(lines):
                i += 1
                command = command.rstrip()[:-1] + " " + lines[i].strip()
            i += 1
            command = command.strip()
            if command and not command.startswith("#"):
                steps.append(Command(document, first_line + start, command))
    return steps


def document_commands(document: Path) -> list[Command]:
    return [step for step in document_steps(document) if step.writes is None]


def not_run_reason(command: Command) -> str | None:
    plain = command.text.removeprefix(".venv/bin/")
    where = command.document.relative_to(ROOT).as_posix()
    for (document, prefix), (other, _) in RUN_ELSEWHERE.items():
        if where == document and plain.startswith(prefix):
            return f"{other} runs the same command"
    return next((why for prefix, why in NOT_RUN.items() if plain.startswith(prefix)), None)


def run_command(command: Command) -> None:
    """Run one documented command in this process, with ``TINY`` budgets for recipes."""
    if command.writes is not None:
        Path(command.writes).parent.mkdir(parents=True, exist_ok=True)
        Path(command.writes).write_text(command.text)
        return
    argv = command.argv
    if not argv:
        raise AssertionError(f"{command}: not a command")
    placeholders = [w for w in argv if "<" in w or w in ("...", "…")]
    assert not placeholders, f"{command}: placeholders {placeholders} cannot run as written"
    old_argv = sys.argv
    try:
        if argv[0] == "-m":
            extra = next(
                (v for k, v in TINY_MODULES.items() if " ".join(argv[1:]).startswith(k)), []
            )
            sys.argv = [argv[1], *argv[2:], *extra]
            runpy.run_module(argv[1], run_name="__main__", alter_sys=True)
        elif argv[0].endswith(".py") and Path(argv[0]).is_file():  # a script of the document
            sys.argv = list(argv)
            runpy.run_path(argv[0], run_name="__main__")
        elif argv[0].startswith("recipes/"):
            recipe = ROOT / argv[0]
            tiny = TINY.get(recipe.name, [])
            if "ensemble_seeds" in command.text or "exp4_offline_validation" in command.text:
                tiny = [o for o in tiny if not o.startswith("evaluation.episodes")]
            if "algorithm=td3bc" in command.text:  # PPO's minibatches are not TD3+BC's
                tiny = [o for o in tiny if "minibatch" not in o]
                tiny += ["algorithm.updates_per_batch=2", "algorithm.batch_size=32"]
            if "hydra/sweeper=bc_optuna" in command.text:  # Optuna's budget: its trials
                tiny = [*tiny, f"hydra.sweeper.n_trials={TINY_OPTUNA_TRIALS}"]
            words = [
                "hydra/launcher=basic" if word in IN_PROCESS_LAUNCHERS else word
                for word in argv[1:]
            ]
            sys.argv = [str(recipe), *words, *tiny]
            runpy.run_path(str(recipe), run_name="__main__")
        else:
            raise AssertionError(f"{command}: add it to NOT_RUN with a reason, or run it here")
    except SystemExit as exit_:
        assert exit_.code in (0, None), f"{command}: exit code {exit_.code}"
    finally:
        sys.argv = old_argv


def test_every_documented_command_is_run_or_says_why_not():
    commands = [c for d in DOCUMENTS for c in document_commands(d)]
    assert len(commands) > 30
    for command in commands:
        argv = command.argv
        written = {s.writes for s in document_steps(command.document) if s.writes}
        runnable = argv and (
            argv[0] == "-m" or argv[0].startswith("recipes/") or argv[0] in written
        )
        assert runnable or not_run_reason(command), f"{command}: neither run nor excused"


def test_a_command_run_elsewhere_is_run_there_after_the_same_steps():
    """The excused copy (README) and the command that runs (docs/experiments.md) follow
    the same recording and dataset commands, so they train on the same data."""
    inputs = ("recipes/record.py", "recipes/build_dataset.py")
    for (document, prefix), (other, other_prefix) in RUN_ELSEWHERE.items():
        steps, found = {}, {}
        for name, start in ((document, prefix), (other, other_prefix)):
            commands = document_commands(ROOT / name)
            at = [
                i
                for i, c in enumerate(commands)
                if c.text.removeprefix(".venv/bin/").startswith(start)
            ]
            assert at, f"{name}: no command starts with {start!r}"
            found[name] = commands[at[0]]
            steps[name] = [
                shlex.join(c.argv) for c in commands[: at[0]] if c.argv and c.argv[0] in inputs
            ]
        assert steps[document] == steps[other], f"{document} and {other} record different data"
        assert shlex.join(found[document].argv) == shlex.join(found[other].argv)
        assert not_run_reason(found[document]) is not None
        assert not_run_reason(found[other]) is None, f"{other} does not run it either"


def test_the_launchers_swapped_here_are_run_by_the_tests_named():
    for launcher, test in IN_PROCESS_LAUNCHERS.items():
        path, name = test.split("::")
        text = (ROOT / path).read_text()
        assert f"def {name}(" in text, f"{test} (named for {launcher}) does not exist"
        assert f'"{launcher}"' in text, f"{test} does not run {launcher}"


def runnable_steps(document: Path) -> list[Command]:
    """The document's file blocks and the commands this test runs, in reading order."""
    return [
        c for c in document_steps(document) if c.writes is not None or not_run_reason(c) is None
    ]


def step_key(step: Command) -> str:
    """What a step does, whichever document it is in: the file it writes and its text, or
    the command's words (the interpreter's path and comments left out)."""
    if step.writes is not None:
        return f"file {step.writes}\n{step.text}"
    return shlex.join(step.argv)


class SharedPrefixes:
    """Working directories after the leading steps that two or more documents share.

    Each document's steps run in a fresh directory; where a document begins with steps
    another document of this session has already run (the same commands, in the same
    order, from an empty directory), it starts from a copy of the directory they left
    instead of running them again. Commands run in-process and are deterministic (seeded
    recordings and training), so the copy holds what running them again would write.
    A step that failed leaves no copy: the next document runs it and fails too.
    """

    def __init__(self, root: Path, documents: list[Path]):
        self.root = root
        keys = [tuple(step_key(s) for s in runnable_steps(d)) for d in documents]
        # prefixes of two or more documents (the directories worth keeping)
        seen: dict[tuple[str, ...], int] = {}
        for document_keys in keys:
            for n in range(1, len(document_keys) + 1):
                seen[document_keys[:n]] = seen.get(document_keys[:n], 0) + 1
        self.shared = {prefix for prefix, count in seen.items() if count > 1}
        self.saved: dict[tuple[str, ...], Path] = {}

    def restore(self, steps: list[Command], workdir: Path) -> int:
        """Copy the longest saved prefix of ``steps`` into ``workdir``; the steps it covers."""
        keys = tuple(step_key(s) for s in steps)
        for n in range(len(keys), 0, -1):
            if keys[:n] in self.saved:
                shutil.copytree(self.saved[keys[:n]], workdir, symlinks=True, dirs_exist_ok=True)
                return n
        return 0

    def save(self, steps: list[Command], n: int, workdir: Path) -> None:
        """Keep ``workdir`` as it is after the first ``n`` steps, if another document shares
        them."""
        prefix = tuple(step_key(s) for s in steps[:n])
        if prefix in self.shared and prefix not in self.saved:
            copy = self.root / str(len(self.saved))
            shutil.copytree(workdir, copy, symlinks=True)
            self.saved[prefix] = copy


@pytest.fixture(scope="session")
def shared_prefixes(tmp_path_factory) -> SharedPrefixes:
    return SharedPrefixes(tmp_path_factory.mktemp("docs_prefixes"), DOCUMENTS)


@pytest.mark.parametrize("document", DOCUMENTS, ids=lambda p: p.name)
def test_documented_commands_run_as_written(document, tmp_path, monkeypatch, shared_prefixes):
    commands = runnable_steps(document)
    if not commands:
        pytest.skip(f"{document.name} has no command to run here")
    # joblib (hydra/launcher=local_parallel) keeps its worker processes between calls, in
    # the directory they started in: a new document starts new workers in its own
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    try:
        done = shared_prefixes.restore(commands, tmp_path)
        for n, command in enumerate(commands[done:], start=done + 1):
            run_command(command)
            shared_prefixes.save(commands, n, tmp_path)
    finally:  # a Ray launcher run in this process leaves its local instance connected
        ray = sys.modules.get("ray")
        if ray is not None and ray.is_initialized():
            ray.shutdown()
