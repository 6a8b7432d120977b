"""Simulators as TorchRL environments.

Every sensor of a plugin's ``Dict`` observation becomes its own key of the tensordict
(``boom_angle``, ``drive_pressure``...), so actors read sensors by name. Observations stay
float32.

- ``num_envs=1``: ``SimulatorBatchEnv(..., unbatched=True)``: one simulator, batch size
  ``[]`` (what TorchRL's ``GymEnv`` gives, at about half its per-step cost: ``GymEnv``
  reads the observation through its spec's ``encode`` and completes the done keys at
  every step; see docs/performance.md).
- ``num_envs=N``: ``SimulatorBatchEnv``, a native ``EnvBase`` that steps N simulators one
  after another in this process and writes their readings straight into preallocated
  arrays, batch size ``[N]``. TorchRL's per-step bookkeeping (~0.2 ms) is then paid once
  for N simulators; measured on one core, 4 pile loaders per env run fastest (beyond that
  the models stop fitting in cache). Gymnasium's ``SyncVectorEnv`` under ``GymWrapper``
  was measured slower than a single env: it merges every ``info`` key into arrays.

A step's tensordict is built from tensors whose shapes and dtypes this class made to
match its specs, without TensorDict's per-entry validation (``TensorDict._new_unsafe``:
~45 us of a ~80 us construction, measured).
The rollout's bookkeeping around it (TorchRL's ``step`` writing ``next``, ``step_mdp``,
the stack of the steps at the end) takes shortcuts for such flat tensordicts that give
TorchRL's results bit for bit (``pilerl.sim.torchrl_steps``; ~110 -> ~60 us per control
step with one simulator, measured).

``device`` defaults to ``None``: the simulators run on the CPU, and a TorchRL env given an
explicit device casts every step's output with ``.to(device)`` (measured: ~0.4 ms of a
~1.3 ms step).
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Callable, Iterator, Sequence

import gymnasium as gym
import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase, ParallelEnv
from torchrl.envs.common import _cache_value
from torchrl.envs.utils import _StepMDP

from .registry import DEFAULT_SIMULATOR, get_simulator, register_gymnasium_envs
from .torchrl_steps import FlatStepMDP, StepsToStack, stack_steps

END_FLAGS = ("done", "terminated", "truncated")
INFO_KEY = "info"  # the ``info_keys`` of a SimulatorBatchEnv, one column each


class SimulatorBatchEnv(EnvBase):
    """N Gymnasium simulators with ``Dict``-of-``Box`` observations, stepped in a loop.

    Args:
        make_env: builds one simulator (called ``num_envs`` times).
        num_envs: batch size.
        device: ``None`` (CPU, no per-step casting) or a torch device.
        info_keys: ``info`` entries also written at reset and at every step, together as
            one float64 entry ``info`` [N, len(info_keys)] (one column per key, NaN where a
            simulator does not report it; one entry costs TorchRL less per step than many).
        reward_dtype: dtype of ``reward`` (float64 keeps the simulator's value exactly).
        unbatched: one simulator (``num_envs`` must be 1) with batch size ``[]``.

    Sub-env ``i`` is reset with seed ``seed + i`` after ``set_seed(seed)``. Sub-envs that
    end are reset individually (TorchRL's ``_reset`` mask), the others keep running.
    A step whose tensordict holds TorchRL's partial-step mask ``_step`` steps only the
    sub-envs it marks; the others keep their readings and end flags.

    Inside ``episodes_ending_together()`` (``pilerl.sim.rollout``: one episode per
    sub-env) the batch's episodes end together: a sub-env whose episode has ended reports
    ``done`` False until every sub-env's has (``running`` says which still run), then
    each reports its own end flags. TorchRL's ``rollout(break_when_any_done=True)`` then
    stops when the last episode ends, without the per-step masked rebuild of its rows
    that ``break_when_all_done`` pays once the first episode has ended (measured: ~0.65
    ms per step, docs/performance.md).
    """

    def __init__(
        self,
        make_env: Callable[[], gym.Env],
        num_envs: int,
        *,
        device: str | None = None,
        info_keys: Sequence[str] = (),
        reward_dtype: torch.dtype = torch.float32,
        unbatched: bool = False,
    ) -> None:
        if num_envs < 1:
            raise ValueError(f"SimulatorBatchEnv: num_envs must be >= 1, got {num_envs}")
        if unbatched and num_envs != 1:
            raise ValueError(f"SimulatorBatchEnv: unbatched needs num_envs=1, got {num_envs}")
        batch = () if unbatched else (num_envs,)
        self._envs = [make_env() for _ in range(num_envs)]
        super().__init__(batch_size=torch.Size(batch), device=device)
        space = self._envs[0].observation_space
        if not isinstance(space, gym.spaces.Dict):
            raise TypeError(f"SimulatorBatchEnv needs a Dict observation space, got {space}")
        self._unbatched = unbatched
        self._names = list(space.spaces)
        # readings land in [num_envs, ...] arrays; an unbatched env hands out row 0
        self._obs = {
            name: np.zeros((num_envs, *box.shape), dtype=np.float32)
            for name, box in space.spaces.items()
        }
        self.observation_spec = Composite(
            {
                name: Bounded(
                    torch.as_tensor(box.low).expand(*batch, *box.shape),
                    torch.as_tensor(box.high).expand(*batch, *box.shape),
                    shape=(*batch, *box.shape),
                    dtype=torch.float32,
                )
                for name, box in space.spaces.items()
            },
            shape=batch,
        )
        self.info_keys = tuple(info_keys)
        self._info = np.full((num_envs, len(self.info_keys)), np.nan)
        if self.info_keys:
            self.observation_spec[INFO_KEY] = Unbounded(
                shape=(*batch, len(self.info_keys)), dtype=torch.float64
            )
        # what a step hands out, each copied into a fresh tensor: [num_envs, ...] arrays, or
        # an unbatched env's row 0 (views, so that the copies cost no indexing per step)
        self._handed_out = {name: self._batch_view(array) for name, array in self._obs.items()}
        if self.info_keys:
            self._handed_out[INFO_KEY] = self._batch_view(self._info)
        action = self._envs[0].action_space
        self.action_spec = Bounded(
            torch.as_tensor(action.low).expand(*batch, *action.shape),
            torch.as_tensor(action.high).expand(*batch, *action.shape),
            shape=(*batch, *action.shape),
            dtype=torch.float32,
        )
        self.reward_spec = Unbounded(shape=(*batch, 1), dtype=reward_dtype)
        self._reward_dtype = torch.empty(0, dtype=reward_dtype).numpy().dtype
        self.done_spec = Composite(
            {flag: Categorical(2, shape=(*batch, 1), dtype=torch.bool) for flag in END_FLAGS},
            shape=batch,
        )
        self._seeds: list[int | None] = [None] * num_envs
        self._terminated = np.zeros((num_envs, 1), dtype=bool)
        self._truncated = np.zeros((num_envs, 1), dtype=bool)
        self._ending_together = False
        self._not_ended = np.zeros((num_envs, 1), dtype=bool)  # the flags held back
        self._not_done = torch.zeros(*batch, 1, dtype=torch.bool)  # cloned at every reset
        self._rollout_steps: StepsToStack | None = None  # within ``rollout``

    @property
    def simulators(self) -> tuple[gym.Env, ...]:
        """The Gymnasium simulators, sub-env order (to render one or read its settings)."""
        return tuple(self._envs)

    @property
    def running(self) -> np.ndarray:
        """bool [num_envs]: the sub-envs whose episode has not ended since their reset."""
        return ~(self._terminated | self._truncated)[:, 0]

    @property
    def end_flags(self) -> tuple[np.ndarray, np.ndarray]:
        """(terminated, truncated), bool [num_envs, 1]: how each sub-env's episode ended
        (both False while it runs), whatever the steps reported."""
        return self._terminated.copy(), self._truncated.copy()

    @contextlib.contextmanager
    def episodes_ending_together(self) -> Iterator[SimulatorBatchEnv]:
        """Within: ended episodes report ``done`` only once every episode has ended (see
        the class docstring)."""
        self._ending_together = True
        try:
            yield self
        finally:
            self._ending_together = False

    def _batch_view(self, array: np.ndarray) -> np.ndarray:
        """``array`` [num_envs, ...] in the env's batch shape (a view)."""
        return array[0] if self._unbatched else array

    def _out(self, array: np.ndarray) -> torch.Tensor:
        """A fresh tensor of ``array`` [num_envs, ...] in the env's batch shape."""
        return torch.from_numpy(self._batch_view(array).copy())

    def _observation_td(self) -> dict[str, torch.Tensor]:
        """The sensors (and ``info`` columns), each a fresh tensor."""
        return {key: torch.from_numpy(array.copy()) for key, array in self._handed_out.items()}

    def _new_td(self, entries: dict[str, torch.Tensor]) -> TensorDictBase:
        """A tensordict of ``entries``, made here in the shapes and dtypes of the specs."""
        return TensorDict._new_unsafe(entries, batch_size=self.batch_size, nested=False)

    def _write_obs(self, index: int, obs: dict, info: dict) -> None:
        for name in self._names:
            self._obs[name][index] = obs[name]
        for column, key in enumerate(self.info_keys):
            self._info[index, column] = float(info.get(key, np.nan))

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if mask is not None:
            mask = mask.reshape(len(self._envs), -1).any(-1).tolist()
        for i, env in enumerate(self._envs):
            if mask is None or mask[i]:
                obs, info = env.reset(seed=self._seeds[i])
                self._seeds[i] = None
                self._write_obs(i, obs, info)
                self._terminated[i], self._truncated[i] = False, False
        entries = self._observation_td()
        for flag in END_FLAGS:
            entries[flag] = self._not_done.clone()
        return self._new_td(entries)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        n = len(self._envs)
        actions = tensordict.get("action").numpy(force=True).reshape(n, -1)
        stepped = tensordict.get("_step", None)
        if stepped is not None:
            stepped = stepped.reshape(n).tolist()
        reward = np.zeros((n, 1), dtype=self._reward_dtype)
        terminated, truncated = self._terminated, self._truncated
        for i, env in enumerate(self._envs):
            if stepped is not None and not stepped[i]:
                continue  # an ended sub-env of a partial step: left as it is
            obs, reward[i, 0], terminated[i, 0], truncated[i, 0], info = env.step(actions[i])
            self._write_obs(i, obs, info)
        if self._ending_together and not (terminated | truncated).all():
            terminated = truncated = self._not_ended  # held back until all have ended
        entries = self._observation_td()
        entries["reward"] = self._out(reward)
        entries["terminated"] = self._out(terminated)
        entries["truncated"] = self._out(truncated)
        entries["done"] = self._out(terminated | truncated)
        return self._new_td(entries)

    def step(self, tensordict: TensorDictBase) -> TensorDictBase:
        """TorchRL's ``step``. A rollout's step (a plain, unlocked tensordict without
        names, ``next`` or partial-step mask ``_step``, on an env without a device) gets
        ``next`` written without TensorDict's checks of a value ``_step`` made in this
        env's batch size; the rest is TorchRL's ``step`` itself."""
        if type(tensordict) is not TensorDict or self.device is not None:
            return super().step(tensordict)
        entries = tensordict._tensordict
        if (
            "next" in entries
            or "_step" in entries
            or tensordict.is_locked
            or tensordict._has_names()
            or tensordict.device is not None
        ):
            return super().step(tensordict)
        self._assert_tensordict_shape(tensordict)
        next_tensordict = self._step_proc_data(self._step(tensordict))
        tensordict._set_str(
            "next", next_tensordict, validated=True, inplace=False, non_blocking=False
        )
        return tensordict

    def _step_proc_data(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        """TorchRL's completion of a step's output (the reward viewed in its spec's shape,
        missing done keys filled in: ~20% of TorchRL's per-step cost, measured), which
        ``_step`` has already done; still run when TorchRL's type checks are on."""
        if self.run_type_checks:
            return super()._step_proc_data(next_tensordict)
        return next_tensordict

    def rollout(
        self,
        max_steps: int,
        policy: Callable | None = None,
        callback: Callable | None = None,
        **kwargs,
    ) -> TensorDictBase:
        """TorchRL's ``rollout``, its steps stacked by ``stack_steps``: the tensordict
        TensorDict's stack gives, without its checks of every entry of every step (~35 of
        the ~110 us TorchRL adds to a control step, measured; docs/performance.md).

        TorchRL's ``rollout`` ends by stacking its steps onto ``out`` when given one; this
        gives it one without entries, sized when the steps are known, so that its stack
        copies nothing, and stacks the steps here. With ``out`` or ``set_truncated`` given,
        or ``return_contiguous`` given as anything but False, it is TorchRL's ``rollout``
        unchanged."""
        if (
            kwargs.get("out") is not None
            or kwargs.get("return_contiguous", False) is not False
            or kwargs.get("set_truncated", False)
        ):
            return super().rollout(max_steps, policy, callback, **kwargs)
        outer, self._rollout_steps = self._rollout_steps, StepsToStack()
        steps = self._rollout_steps
        try:
            super().rollout(max_steps, policy, callback, out=steps.out, **kwargs)
        finally:
            self._rollout_steps = outer  # a rollout called inside another one's policy
        return stack_steps(steps.steps, steps.dim).refine_names(..., "time")

    def _rollout_nonstop(self, **kwargs) -> list[TensorDictBase]:
        return self._keep_steps(super()._rollout_nonstop(**kwargs))

    def _rollout_stop_early(self, **kwargs) -> list[TensorDictBase]:
        return self._keep_steps(super()._rollout_stop_early(**kwargs))

    def _keep_steps(self, steps: list[TensorDictBase]) -> list[TensorDictBase]:
        if self._rollout_steps is not None:
            self._rollout_steps.keep(steps, dim=len(self.batch_size))
        return steps

    @property
    @_cache_value
    def _step_mdp(self) -> FlatStepMDP:
        """TorchRL's ``step_mdp`` (``EnvBase._step_mdp``), on flat tensordicts without
        TensorDict's per-entry checks (``pilerl.sim.torchrl_steps``)."""
        return FlatStepMDP(_StepMDP(self, exclude_action=False))

    def seed_episodes(self, seeds: Sequence[int]) -> None:
        """Reset sub-env ``i`` with seed ``seeds[i]`` at its next reset."""
        if len(seeds) != len(self._envs):
            raise ValueError(
                f"SimulatorBatchEnv.seed_episodes: {len(seeds)} seeds for {len(self._envs)} "
                "sub-envs"
            )
        self._seeds = [int(seed) for seed in seeds]

    def _set_seed(self, seed: int | None) -> int | None:
        if seed is None:
            return None
        self._seeds = [seed + i for i in range(len(self._envs))]
        return seed + len(self._envs)

    def close(self, *, raise_if_closed: bool = True) -> None:
        for env in self._envs:
            env.close()
        super().close(raise_if_closed=raise_if_closed)


def make_torchrl_env(
    name: str = DEFAULT_SIMULATOR,
    *,
    num_envs: int = 1,
    workers: int = 1,
    device: str | None = None,
    seed: int | None = None,
    use_buffers: bool = True,
    **kwargs,
) -> EnvBase:
    """A TorchRL env around simulator ``name``; ``kwargs`` go to the simulator.

    Args:
        num_envs: simulators per process (``1``: batch ``[]``; else ``[num_envs]``).
        workers: ``> 1``: a TorchRL ``ParallelEnv`` of ``workers`` processes, each stepping
            ``num_envs`` simulators (batch ``[workers]`` or ``[workers, num_envs]``); the
            sub-envs are seeded ``seed``, ``seed + 1``, ... in worker order when built.
        use_buffers: (``workers > 1``) TorchRL's shared-memory buffers (its default). The
            parent then spin-polls the workers' done flags at every step, a busy loop;
            without them it blocks on the workers' pipes but pickles every step's
            tensordicts, which cost it as much CPU (measured, docs/performance.md). Either
            way a lockstep env needs a core for its parent beside the workers'.
    """
    if num_envs < 1:
        raise ValueError(f"make_torchrl_env: num_envs must be >= 1, got {num_envs}")
    if workers < 1:
        raise ValueError(f"make_torchrl_env: workers must be >= 1, got {workers}")
    plugin = get_simulator(name)
    if workers > 1:
        # each worker's env is seeded where it is built (TorchRL's ``ParallelEnv.set_seed``
        # hands worker k a hash of worker k-1's seed, not ``seed + k * num_envs``)
        worker_seeds = [None if seed is None else seed + k * num_envs for k in range(workers)]
        return ParallelEnv(
            workers,
            [
                functools.partial(_worker_env, name, num_envs, device, worker_seed, kwargs)
                for worker_seed in worker_seeds
            ],
            use_buffers=use_buffers,
            num_sub_threads=1,
        )
    register_gymnasium_envs()
    env = SimulatorBatchEnv(
        lambda: gym.make(plugin.gym_id, **kwargs),
        num_envs,
        device=device,
        unbatched=num_envs == 1,
    )
    if seed is not None:
        env.set_seed(seed)
    return env


def _worker_env(
    name: str, num_envs: int, device: str | None, seed: int | None, kwargs: dict
) -> EnvBase:
    """One worker process's env (module level: the workers import it by name)."""
    torch.set_num_threads(1)
    return make_torchrl_env(name, num_envs=num_envs, device=device, seed=seed, **kwargs)
