"""torch's dropout masks drawn one or two steps ahead on a second thread, bit for bit.

A DANNet step at batch 512 spends about 30% of its time in ``bernoulli_`` (torch's CPU
dropout draws, element by element, on the thread that runs the step). Within an epoch
the draws are known in advance: the batch sizes follow from the row count, the dropout
layers and their widths from the model, and nothing else draws from the global generator
while the epoch runs (the batch order has its own generator). ``MasksAhead`` therefore
clones the global generator's state, draws each step's masks in the order the forward
pass would (layer after layer, the same ``empty_like(x).bernoulli_(1 - p).div_(1 - p)``
that ``torch.nn.functional.dropout`` runs on the CPU, with the dtype and device of the
layer's input, so the scale 1/q is rounded as torch rounds it) on a worker thread while
the main thread computes the previous step, and at the end of the epoch hands the
generator's state back to the global one. Losses, weights and the saved RNG state are
bit-identical to drawing in the step (tested, in float32 and float64). It pays only where
a second core is idle: on a loaded machine the worker competes with the step for the same
cores. Layers with p = 0 are left alone: torch's dropout returns their input and draws
nothing.

``masks="packed"`` draws ``packed`` masks ahead instead (``pilerl.training.dropout_masks``):
the same ``packed_keep_masks`` call per layer and step as ``PackedDropout`` makes in the
step, on the cloned generator, so the run is bit-identical to ``dropout_masks="packed"``
drawn in the step (tested). The masks are float32 whatever the layer's dtype, as
``PackedDropout``'s.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress

import torch
from torch import nn

from .dropout_masks import (
    DropoutSite,
    check_dropout_masks,
    dropout_layers,
    packed_keep_masks,
    restore_dropout,
)

STEPS_AHEAD = 2  # masks of at most this many steps wait in memory


class _Fed(nn.Module):
    """Dropout that takes its mask from ``feed`` (layer ``index`` of the current step)."""

    def __init__(self, p: float, feed: MasksAhead, index: int) -> None:
        super().__init__()
        self.p, self.feed, self.index = p, feed, index

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.training or self.p == 0:
            return x
        mask = self.feed.current[self.index]
        if mask.shape != x.shape:
            raise RuntimeError(
                f"MasksAhead: a mask of shape {tuple(mask.shape)} was drawn for dropout "
                f"layer {self.index}, which got {tuple(x.shape)}"
            )
        packed = self.feed.masks == "packed"  # float32 masks, as PackedDropout's
        dtype = torch.float32 if packed else x.dtype
        if mask.dtype != dtype or mask.device != x.device:
            raise RuntimeError(
                f"MasksAhead: a {mask.dtype} mask on {mask.device} was drawn for dropout "
                f"layer {self.index}, which got {x.dtype} on {x.device}"
            )
        if not packed and not x.is_contiguous():
            # torch draws into empty_like(x), which keeps x's memory layout: the same
            # generator fills another element order, so drawn-ahead masks would differ
            raise RuntimeError(
                f"MasksAhead: dropout layer {self.index} got a non-contiguous input "
                f"(strides {x.stride()} for shape {tuple(x.shape)}); masks drawn ahead are "
                "only bit-identical for contiguous inputs: train without draw_ahead"
            )
        return x * mask


class MasksAhead:
    """The dropout masks of one epoch's steps, drawn ahead from a clone of the global
    generator (see the module docstring). Use through ``masks_ahead``."""

    def __init__(self, layers: Sequence[DropoutSite], masks: str = "bernoulli") -> None:
        check_dropout_masks(masks, "MasksAhead")
        self.layers = list(layers)
        self.masks = masks
        self.current: list[torch.Tensor] = []
        self._queue: queue.Queue = queue.Queue(maxsize=STEPS_AHEAD)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._generator = torch.Generator()

    def start_epoch(self, rows_per_step: Sequence[int]) -> None:
        """Begin drawing the masks of steps of these batch sizes from the global state."""
        self._generator.set_state(torch.get_rng_state())
        self._stop.clear()
        self._thread = threading.Thread(
            target=self._draw, args=(list(rows_per_step),), name="dropout masks", daemon=True
        )
        self._thread.start()

    def next_step(self) -> None:
        """Make the next step's masks ``current`` (blocks until they are drawn)."""
        item = self._queue.get()
        if isinstance(item, BaseException):
            raise RuntimeError("MasksAhead: drawing the dropout masks failed") from item
        self.current = item

    def end_epoch(self) -> None:
        """Wait for the worker and give its generator state to the global generator."""
        self._finish()
        torch.set_rng_state(self._generator.get_state())

    def abandon(self) -> None:
        """Stop the worker (the epoch did not end; the global state is left as it is)."""
        self._stop.set()
        self._finish()

    def _finish(self) -> None:
        while self._thread is not None and self._thread.is_alive():
            with suppress(queue.Empty):  # a worker blocked on a full queue sees the stop
                self._queue.get(timeout=0.01)
        self._thread = None
        while not self._queue.empty():
            self._queue.get_nowait()
        self.current = []

    def _draw(self, rows_per_step: list[int]) -> None:
        try:
            for rows in rows_per_step:
                masks = []
                for p, shape, dtype, device in self.layers:
                    options = {"dtype": dtype, "device": device}  # as empty_like(x)
                    if self.masks == "packed":  # PackedDropout's draw, p = 1 included
                        drawn = packed_keep_masks([(rows, *shape)], p, generator=self._generator)
                        masks.append(drawn[0])
                    elif p == 1:  # multiplied by zero: no draw
                        masks.append(torch.zeros(rows, *shape, **options))
                    else:
                        noise = torch.empty(rows, *shape, **options)
                        noise.bernoulli_(1 - p, generator=self._generator).div_(1 - p)
                        masks.append(noise)
                while not self._stop.is_set():
                    try:
                        self._queue.put(masks, timeout=0.1)
                        break
                    except queue.Full:
                        continue
                if self._stop.is_set():
                    return
        except BaseException as error:  # handed to the main thread by next_step
            self._queue.put(error)


@contextmanager
def masks_ahead(
    module: nn.Module, run: Callable[[], object], masks: str = "bernoulli"
) -> Iterator[MasksAhead | None]:
    """Within the block, ``module``'s dropout layers with p > 0 take their masks
    (``bernoulli``: torch's, ``packed``: ``PackedDropout``'s) from the returned
    ``MasksAhead`` (``None`` when it has no such layer: nothing to draw). ``run()`` is a
    forward pass of one row, to find the layers, their widths and dtypes."""
    check_dropout_masks(masks, "masks_ahead")
    layers = {name: site for name, site in dropout_layers(module, run).items() if site.p > 0}
    elsewhere = {str(site.device) for site in layers.values() if site.device.type != "cpu"}
    if elsewhere:  # torch draws there with another generator (and another kernel)
        raise ValueError(
            f"masks_ahead: draws torch's CPU dropout masks; the model's dropout runs on "
            f"{sorted(elsewhere)}"
        )
    if not layers:
        yield None
        return
    feed = MasksAhead(list(layers.values()), masks)
    replaced = {name: module.get_submodule(name) for name in layers}
    for i, (name, layer) in enumerate(replaced.items()):  # in the order they are called
        module.set_submodule(name, _Fed(layer.p, feed, i).train(layer.training))
    try:
        yield feed
    finally:
        feed.abandon()
        restore_dropout(module, replaced)
