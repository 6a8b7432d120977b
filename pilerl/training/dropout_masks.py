"""Dropout masks for training: torch's ``bernoulli`` draws or ``packed`` random words.

torch's ``nn.Dropout`` on the CPU draws its mask with ``bernoulli_``: one uniform number
per element from the global Mersenne Twister, element by element (about 8 ns an element
on the development machine: 30% of a DANNet step at batch 512, and the same share of
every ensemble member's step).

``packed`` masks take their randomness from the same global generator, but as 64-bit
words (``random_`` over the full int64 range) split into four 16-bit integers: an element
is kept when its integer is below ``round(q * 2**16)`` (shifted to int16's range), with
q = 1 - p the keep probability. A word decides four elements, so the masks cost about a
sixth of torch's. Kept elements are scaled by 1/q exactly as torch's dropout scales them
(the mask is {0, 1} divided by q in float32), so only *which* elements are kept differs:
each element is kept independently with probability ``round(q * 2**16) / 2**16`` (for
p = 0.35: 0.6499939 instead of 0.65, a difference of 6e-6, far below what a training
run can resolve). A fixed seed gives other masks than torch's, hence other weights: the
same distribution, not the same draws (docs/performance.md, "Training and actors").
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import NamedTuple

import torch
from torch import nn

DROPOUT_MASKS = ("bernoulli", "packed")
LANES_PER_WORD = 4  # 16-bit integers per 64-bit random word
LANE_VALUES = 1 << 16


def check_dropout_masks(name: str | None, where: str) -> None:
    """Refuse an unknown generator name (``None`` = the trainer's default)."""
    if name is not None and name not in DROPOUT_MASKS:
        raise ValueError(f"{where}: unknown {name!r}; known: {list(DROPOUT_MASKS)}")


def packed_keep_masks(
    shapes: Sequence[Sequence[int]],
    drop_probability: float,
    *,
    generator: torch.Generator | None = None,
) -> list[torch.Tensor]:
    """Dropout multipliers of the given shapes (float32: 0 or 1/q, q = 1 - p), drawn with
    one ``random_`` call on ``generator`` (``None``: the global one) for all of them."""
    if not 0.0 <= drop_probability <= 1.0:
        raise ValueError(
            f"packed_keep_masks: drop probability must be in [0, 1], got {drop_probability}"
        )
    keep_probability = 1.0 - drop_probability
    sizes = [math.prod(shape) for shape in shapes]
    total = sum(sizes)
    kept_values = round(keep_probability * LANE_VALUES)  # lanes 0..kept_values-1 keep
    if kept_values >= LANE_VALUES:  # p = 0: nothing dropped, nothing drawn (as torch)
        flat = torch.ones(total)
    else:
        words = torch.empty(-(-total // LANES_PER_WORD), dtype=torch.int64)
        # every bit random (random_()'s default int64 range leaves the top bit 0)
        words.random_(-(2**63), None, generator=generator)
        lanes = words.view(torch.int16)[:total]  # uniform over [-2**15, 2**15)
        flat = (lanes < kept_values - LANE_VALUES // 2).to(torch.float32)
        if keep_probability > 0:
            flat.div_(keep_probability)  # the scale torch's dropout applies
    return [part.view(*shape) for part, shape in zip(flat.split(sizes), shapes, strict=True)]


class PackedDropout(nn.Module):
    """``nn.Dropout`` with a ``packed`` mask (see the module docstring)."""

    def __init__(self, p: float) -> None:
        super().__init__()
        self.p = p

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0:
            return x
        return x * packed_keep_masks([x.shape], self.p)[0]


class GivenMaskDropout(nn.Module):
    """Dropout whose multiplier is the buffer ``mask`` (0 or 1/q), set by the caller: how
    ``torch.func.functional_call`` hands each ensemble member its own mask.

    The mask must have the input's shape (inside ``vmap``: one member's mask and input):
    one multiplier per element, as torch's dropout draws it. A mask of another shape is
    refused, naming both shapes, rather than broadcast (a mask of one row broadcast over
    a batch would drop the same features of every row).
    """

    def __init__(self, p: float) -> None:
        super().__init__()
        self.p = p
        self.register_buffer("mask", None, persistent=False)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0:
            return x
        if self.mask is None:
            raise RuntimeError("GivenMaskDropout: training needs a mask (the buffer 'mask')")
        if self.mask.shape != x.shape:
            raise ValueError(
                f"GivenMaskDropout: the mask has shape {tuple(self.mask.shape)}, the input "
                f"{tuple(x.shape)}; they must be equal (one multiplier per element)"
            )
        return x * self.mask


class DropoutSite(NamedTuple):
    """What one dropout layer sees: its drop probability and its input's row shape, dtype
    and device (the mask torch's dropout draws there is ``empty_like`` its input)."""

    p: float
    shape: tuple[int, ...]  # one row's features
    dtype: torch.dtype
    device: torch.device


def dropout_layers(module: nn.Module, run: Callable[[], object]) -> dict[str, DropoutSite]:
    """Each ``nn.Dropout`` of ``module`` that ``run()`` (a forward pass of one row) calls, in
    the order it is called: name -> its ``DropoutSite``. Runs in eval mode (no draws) and
    without gradients; the mode is put back."""
    found: dict[str, DropoutSite] = {}

    def record(name: str):
        def hook(layer: nn.Module, inputs: tuple[torch.Tensor, ...], _) -> None:
            x = inputs[0]
            found.setdefault(name, DropoutSite(layer.p, tuple(x.shape[1:]), x.dtype, x.device))

        return hook

    hooks = [
        layer.register_forward_hook(record(name))
        for name, layer in module.named_modules()
        if type(layer) is nn.Dropout
    ]
    was_training = module.training
    module.eval()
    try:
        with torch.no_grad():
            run()
    finally:
        module.train(was_training)
        for hook in hooks:
            hook.remove()
    return found


def replace_dropout(module: nn.Module, make: type[nn.Module]) -> dict[str, nn.Dropout]:
    """Replace every ``nn.Dropout`` in ``module`` by ``make(p)``; returns the replaced
    modules by name (to put back with ``restore_dropout``)."""
    replaced = {name: child for name, child in module.named_modules() if type(child) is nn.Dropout}
    for name, dropout in replaced.items():
        module.set_submodule(name, make(dropout.p).train(dropout.training))
    return replaced


def restore_dropout(module: nn.Module, replaced: dict[str, nn.Dropout]) -> None:
    """Put back the modules ``replace_dropout`` took out."""
    for name, dropout in replaced.items():
        module.set_submodule(name, dropout)


@contextmanager
def dropout_masks(module: nn.Module, name: str) -> Iterator[None]:
    """Within the block, ``module``'s dropout layers draw ``name`` masks (``bernoulli``:
    torch's own, unchanged; ``packed``: ``PackedDropout``)."""
    check_dropout_masks(name, "dropout_masks")
    if name == "bernoulli":
        yield
        return
    replaced = replace_dropout(module, PackedDropout)
    try:
        yield
    finally:
        restore_dropout(module, replaced)
