"""One rollout: TorchRL's ``EnvBase.rollout`` over a batch of simulators.

Recording demonstrations, closed-loop evaluation, videos and the scoop recipe all run
their episodes here; only the policy differs: an ``OperatorModule`` (one operator per
batch element, ``pilerl.operators``) or an actor (``pilerl.policies``). Both are
TensorDict modules reading the sensors by name and writing ``action``.

``rollout(env, policy, seed=s)`` runs one episode in each of the env's N simulators:
simulator ``i`` starts from seed ``s + i`` (``SimulatorBatchEnv.set_seed``), so a batch
of N episodes starting at seed ``s`` is the same as N single-episode rollouts with seeds
``s, s + 1, ...``. Episodes end at different steps: a simulator whose episode has ended
is no longer stepped nor acted for (TorchRL's partial-step mask ``_step``, which the
policy reads too), and the rollout ends when all have
(``SimulatorBatchEnv.episodes_ending_together``: TorchRL's ``break_when_any_done`` then
stops at the last end, without rebuilding every row under a mask as
``break_when_all_done`` does). The result's tensordict has batch ``[N, T]``
(``T`` = the longest episode); an ended episode's rows repeat its last row (filled in
once, after the rollout), and ``Rollout.episode(i)`` cuts episode ``i`` to its own length.

Each row ``t`` holds the readings before step ``t`` (sensors, and the ``info`` columns of
the reset or the previous step), what the policy wrote, and under ``"next"`` the
readings, ``info``, ``reward`` and end flags after it: the layout of a demonstration
episode (``pilerl.data.schema``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tqdm import tqdm

from .registry import make_gym_env
from .torchrl_env import INFO_KEY, SimulatorBatchEnv

MAX_STEPS = 1_000_000  # a bound for simulators that never end; episodes end long before
PARTIAL_STEP_KEY = "_step"  # TorchRL's mask of the simulators a partial step steps


def make_rollout_env(
    simulator: str,
    env_kwargs: Mapping[str, object],
    *,
    num_envs: int = 1,
    info_keys: Sequence[str] = (),
    each: Sequence[Mapping[str, object]] = (),
) -> SimulatorBatchEnv:
    """``num_envs`` simulators ``simulator(**env_kwargs)`` as one TorchRL env for ``rollout``.

    ``info_keys`` are the ``info`` entries copied into every row (one float64 column each
    of the entry ``info``, NaN where the simulator does not report one; ``Rollout.info``
    reads them by name); the reward is kept in float64, as the simulator reports it.
    ``each``: one mapping of arguments per simulator, on top of ``env_kwargs`` (e.g. each
    its own ``condition``, which replaces one in ``env_kwargs``); ``num_envs`` is then
    ``len(each)``, and a different ``num_envs`` is refused.
    """
    kwargs = dict(env_kwargs)
    own = iter([dict(options) for options in each])
    if each:
        if num_envs not in (1, len(each)):
            raise ValueError(
                f"make_rollout_env: num_envs={num_envs} but {len(each)} per-simulator "
                "argument sets in each="
            )
        num_envs = len(each)
    return SimulatorBatchEnv(
        lambda: make_gym_env(simulator, **{**kwargs, **next(own, {})}),
        num_envs,
        info_keys=info_keys,
        reward_dtype=torch.float64,
    )


def sensor_names(env: SimulatorBatchEnv) -> list[str]:
    """The simulator's sensor names, in the order it declares them (its ``sensor_units``;
    Gymnasium's ``Dict`` space sorts them by name, which is the order otherwise)."""
    simulator = env.simulators[0]
    declared = getattr(simulator.unwrapped, "sensor_units", None)
    return list(declared) if declared else list(simulator.observation_space.spaces)


def control_period_s(env: SimulatorBatchEnv) -> float:
    """The simulator's control period [s]."""
    return float(env.simulators[0].unwrapped.dt)


def control_names(env: SimulatorBatchEnv) -> list[str]:
    """The simulator's control names (empty if it does not name them)."""
    return list(getattr(env.simulators[0].unwrapped, "control_names", ()))


@dataclass
class Rollout:
    """Episodes run side by side.

    Attributes:
        data: batch ``[N, T]``; rows past an episode's end repeat its last row.
        lengths: control steps of each episode.
        seeds: env seed of each episode.
        info_keys: the env's ``info`` columns (``Rollout.info`` reads them by name).
        frames: per episode, rendered RGB frames (empty unless asked for); frame ``k``
            shows the state after ``k * frame_stride`` steps, and the final state when
            the episode's length is a multiple of ``frame_stride``.
        frame_stride: control steps between frames (0: none rendered).
    """

    data: TensorDictBase
    lengths: list[int]
    seeds: list[int]
    info_keys: tuple[str, ...] = ()
    frames: list[list[np.ndarray]] = field(default_factory=list)
    frame_stride: int = 0

    def episode(self, index: int) -> TensorDictBase:
        """Episode ``index``'s rows, batch ``[lengths[index]]``."""
        return self.data[index, : self.lengths[index]]

    def info(self, index: int, key: str) -> np.ndarray:
        """``info[key]`` of episode ``index``, float64 [length + 1]: at reset, then after
        each step (NaN where the simulator did not report it)."""
        if key not in self.info_keys:
            raise KeyError(f"Rollout.info: {key!r} was not carried; info_keys {self.info_keys}")
        column = self.info_keys.index(key)
        rows = self.episode(index)
        start = rows.get(INFO_KEY)[:1, column]
        after = rows.get(("next", INFO_KEY))[:, column]
        return torch.cat([start, after]).numpy()


def rollout(
    env: SimulatorBatchEnv,
    policy: Callable[[TensorDictBase], TensorDictBase],
    *,
    seed: int | Sequence[int],
    max_steps: int = MAX_STEPS,
    frame_stride: int = 0,
    progress: str | None = None,
) -> Rollout:
    """One episode per simulator of ``env``, simulator ``i`` seeded ``seed + i``.

    Args:
        env: from ``make_rollout_env``.
        policy: a TensorDict module writing ``action``; its ``reset()``, if it has one,
            is called first (operators start each episode afresh).
        seed: env seed of the first episode, or one seed per simulator.
        max_steps: stop after this many steps even if episodes go on.
        frame_stride: render every simulator (made with ``render_mode="rgb_array"``)
            after reset and every ``frame_stride`` steps (0: no frames).
        progress: if given, a progress bar (control steps) with this label.
    """
    n = int(env.batch_size[0])
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset()
    seeds = [seed + i for i in range(n)] if isinstance(seed, int) else [int(s) for s in seed]
    env.seed_episodes(seeds)
    start = env.reset()
    frames: list[list[np.ndarray]] = [[] for _ in range(n)]
    running = np.ones(n, dtype=bool)
    ended_at = np.zeros(n, dtype=np.int64)  # steps of each ended episode (0: runs on)
    bar = tqdm(desc=progress, unit="step", leave=False, disable=progress is None, mininterval=1.0)
    steps = 0

    def film(stepped: np.ndarray) -> None:
        for i in np.flatnonzero(stepped):
            frames[i].append(env.simulators[i].render())

    def after_step(_env, tensordict: TensorDictBase) -> None:
        # called after every step but the last: the state after ``steps`` steps
        nonlocal steps, running
        steps += 1
        bar.update()
        if frame_stride and steps % frame_stride == 0:
            film(running)
        running = env.running
        ended_at[(ended_at == 0) & ~running] = steps
        tensordict.set(PARTIAL_STEP_KEY, torch.from_numpy(running.copy()))

    if frame_stride:
        film(running)
    start.set(PARTIAL_STEP_KEY, torch.ones(n, dtype=torch.bool))
    with torch.no_grad(), env.episodes_ending_together():
        data = env.rollout(
            max_steps,
            policy,
            callback=after_step,
            auto_reset=False,
            tensordict=start,
            break_when_any_done=True,
        )
        terminated, truncated = env.end_flags
    bar.update()
    bar.close()
    last = data.batch_size[1]
    lengths = [int(at) if at else last for at in ended_at]
    data = _hold_ended_rows(data.exclude(PARTIAL_STEP_KEY), lengths, terminated, truncated)
    if frame_stride and last % frame_stride == 0:  # the final state of the last episodes
        film(np.array([length == last for length in lengths]))
    return Rollout(
        data=data,
        lengths=lengths,
        seeds=seeds,
        info_keys=env.info_keys,
        frames=frames,
        frame_stride=frame_stride,
    )


def _hold_ended_rows(
    data: TensorDictBase, lengths: list[int], terminated: np.ndarray, truncated: np.ndarray
) -> TensorDictBase:
    """``data`` [N, T] with each episode's end flags written into its last row (the env
    held them back while other episodes ran) and that row repeated after it."""
    last = data.batch_size[1]
    after = data.get("next")
    for i, length in enumerate(lengths):
        if terminated[i, 0] or truncated[i, 0]:  # also an episode ending on the last row
            end = length - 1
            after.get("terminated")[i, end] = bool(terminated[i, 0])
            after.get("truncated")[i, end] = bool(truncated[i, 0])
            after.get("done")[i, end] = True
    for key in data.keys(include_nested=True, leaves_only=True):
        column = data.get(key)
        for i, length in enumerate(lengths):
            if length < last:
                column[i, length:] = column[i, length - 1]
    return data


class RowByRow(TensorDictModuleBase):
    """Runs ``policy`` on each batch row alone (batch ``[]``), skipping ended episodes.

    A batched matrix product rounds differently from a one-row one (measured: the actions
    of NNetV2, ANNet and DANNet on a batch of 4 differ in the last bits from the same rows
    alone), and a closed loop amplifies such differences. Row by row, an episode's actions
    do not depend on which episodes share its batch: they are those of the unbatched
    actor, as in deployment.
    """

    def __init__(self, policy: TensorDictModuleBase) -> None:
        super().__init__()
        self.policy = policy
        self.in_keys = list(policy.in_keys)
        self.out_keys = list(policy.out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        n = int(tensordict.batch_size[0])
        active = tensordict.get(PARTIAL_STEP_KEY, None)
        inputs = tensordict.select(*self.in_keys)
        rows = {}
        for i in range(n):
            if active is None or bool(active[i]):
                rows[i] = self.policy(inputs[i].clone())
        first = next(iter(rows.values()))
        for key in self.out_keys:
            value = first.get(key)
            column = torch.zeros(n, *value.shape, dtype=value.dtype)
            for i, row in rows.items():
                column[i] = row.get(key)
            tensordict.set(key, column)
        return tensordict
