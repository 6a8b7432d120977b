"""TorchRL's per-step bookkeeping for the flat tensordicts of a ``SimulatorBatchEnv``.

TorchRL 0.14 walks a step's tensordict through TensorDict's general entry points, which
check at every entry whether it is a nested tensordict, a non-tensor or a lazy stack. A
simulator's tensordicts hold plain tensors under string keys, one level under ``"next"``;
for those (measured per control step, of the ~110 us TorchRL added; docs/performance.md):

- ``FlatStepMDP``: ``step_mdp`` (``torchrl.envs.utils._StepMDP``, the next step's root
  tensordict from a step's output, run at every step of ``rollout`` and of the
  collectors) picks the same entries in the same order with dictionary operations
  (~15 -> ~5 us);
- ``stack_steps``: the stack that ends ``rollout`` calls ``torch.stack`` on each entry
  as TensorDict's stack does, without its checks of every entry of every step
  (~35 -> ~9 us).

Anything else (nested tensordicts a policy wrote, non-tensor data, names, lazy stacks,
steps with other keys or shapes) goes through TorchRL's and TensorDict's own code.
"""

from __future__ import annotations

import torch
from tensordict import LazyStackedTensorDict, TensorDict, TensorDictBase, lazy_legacy
from torchrl.envs.utils import _StepMDP


class FlatStepMDP:
    """``_StepMDP`` (``exclude_action=False``, TorchRL's ``EnvBase._step_mdp``) for flat
    tensordicts: the root's entries but the excluded ones (``next``, the end flags, the
    reward, ``_reset``), then the observations and end flags of ``next``, each the same
    tensor object TorchRL's would place, in the same key order."""

    def __init__(self, general: _StepMDP) -> None:
        self._general = general
        excluded, from_next = general.exclude_from_root, general.keys_from_next
        # the fast path needs string keys one level deep and TorchRL's keep-other layout
        self._flat = (
            general.keep_other
            and all(sub is None for sub in excluded.values())
            and all(sub is None for sub in from_next.values())
        )
        self._excluded = frozenset(excluded)
        self._from_next = tuple(from_next)

    def __call__(self, tensordict: TensorDictBase) -> TensorDictBase:
        if not self._flat or type(tensordict) is not TensorDict or tensordict._has_names():
            return self._general(tensordict)
        root = tensordict._tensordict
        after = root.get("next")
        if type(after) is not TensorDict:
            return self._general(tensordict)
        entries = {}
        for key, value in root.items():
            if key in self._excluded:
                continue
            if type(value) is not torch.Tensor:
                return self._general(tensordict)  # a nested tensordict, non-tensor data
            entries[key] = value
        following = after._tensordict
        for key in self._from_next:
            value = following.get(key)
            if value is None:
                continue  # absent: TorchRL's allows it too
            if type(value) is not torch.Tensor:
                return self._general(tensordict)
            entries[key] = value
        return TensorDict._new_unsafe(
            entries, batch_size=tensordict.batch_size, device=tensordict.device, nested=False
        )


def stack_steps(steps: list[TensorDictBase], dim: int) -> TensorDictBase:
    """``LazyStackedTensorDict.maybe_dense_stack(steps, dim)``, which ends TorchRL's
    ``rollout``, without its per-entry checks where the steps are TensorDicts of the same
    string keys holding plain tensors (nested one ``next`` deep or more): there it is
    ``torch.stack`` of each entry, as TensorDict's stack calls it, in the first step's key
    order. Anything else (other keys at some step, shapes that differ, non-tensor data,
    named dimensions, TensorDict's lazy mode) gets TensorDict's own stack."""
    dense = None if lazy_legacy() else _dense_stack(steps, dim)
    return LazyStackedTensorDict.maybe_dense_stack(steps, dim) if dense is None else dense


def _dense_stack(steps: list[TensorDictBase], dim: int) -> TensorDict | None:
    """The dense stack of ``steps`` along ``dim``, or None where TensorDict's stack would
    do something else than ``torch.stack`` each entry."""
    first = steps[0]
    batch_size, keys = first.batch_size, first._tensordict.keys()
    for step in steps:
        if type(step) is not TensorDict or step._has_names() or step.batch_size != batch_size:
            return None
        if step._tensordict.keys() != keys:
            return None
    entries = {}
    for key in keys:
        values = [step._tensordict[key] for step in steps]
        kind = type(values[0])
        if kind is torch.Tensor:
            if not all(type(value) is torch.Tensor for value in values):
                return None
            try:
                entries[key] = torch.stack(values, dim)
            except RuntimeError:  # shapes differ: TensorDict's stack makes a lazy stack
                return None
        elif kind is TensorDict:
            nested = _dense_stack(values, dim)
            if nested is None:
                return None
            entries[key] = nested
        else:
            return None
    stacked_size = list(batch_size)
    stacked_size.insert(dim, len(steps))
    return TensorDict._new_unsafe(entries, batch_size=torch.Size(stacked_size), device=first.device)


class StepsToStack:
    """A rollout's steps, kept for ``stack_steps``; ``out``: the tensordict without entries
    TorchRL's ``rollout`` stacks them onto (nothing to copy), sized by ``keep``."""

    def __init__(self) -> None:
        self.out = TensorDict()
        self.steps: list[TensorDictBase] = []
        self.dim = 0

    def keep(self, steps: list[TensorDictBase], *, dim: int) -> None:
        """Keeps ``steps``, to be stacked along ``dim`` (none: TorchRL's stack refuses
        the empty list, as without ``out``)."""
        self.steps, self.dim = steps, dim
        if steps:
            stacked_size = list(steps[0].batch_size)
            stacked_size.insert(dim, len(steps))
            self.out.batch_size = torch.Size(stacked_size)
