"""torch's RAdam step computed over all parameters at once, bit for bit.

``torch.optim.RAdam`` on the CPU runs its single-tensor step: for each of a model's
parameters (14 for a DANNet) about a dozen element-wise operations and a ``.item()`` of the
step count, so a step of RAdam is some 180 small kernels, 15% of a DANNet step at batch
512. ``FlatRAdam`` keeps the two moment estimates of every parameter in one contiguous
tensor each and runs the same operations, in the same order and with the same Python
scalars, once over all of them: an element-wise operation computes each element from the
same inputs whatever tensor holds it (on the builds tested: torch 2.13 CPU), so the
parameters, moments and losses are bit-identical to torch's step (tested against
``torch.optim.RAdam`` over whole training runs; an operation whose vectorised and
scalar code rounded differently would show there).

The torch optimiser stays the owner of the state that checkpoints save and resume:
``FlatRAdam`` reads its moments and step counts when made and writes them back with
``store()`` (``train_bc`` calls it before every checkpoint and at the end of training).
Only the settings ``train_bc`` uses are supported (no weight decay, ``maximize``,
``capturable``, ``differentiable`` or complex parameters); others are refused.
"""

from __future__ import annotations

import torch

# the settings FlatRAdam implements, as torch.optim.RAdam's param group spells them
SUPPORTED = {
    "weight_decay": 0,
    "maximize": False,
    "capturable": False,
    "differentiable": False,
    "decoupled_weight_decay": False,
}
RECTIFY_ABOVE = 5.0  # rho_t above which torch's RAdam applies the adaptive rate


class FlatRAdam:
    """The step of ``optimizer`` (a ``torch.optim.RAdam``) over flat moment buffers.

    Use ``zero_grad()`` and ``step()`` as the optimiser's, and ``store()`` before reading
    ``optimizer.state_dict()``. Every parameter must get a gradient in every step (torch
    skips a parameter without one; here that is an error, never a silent difference).
    """

    def __init__(self, optimizer: torch.optim.RAdam) -> None:
        if type(optimizer) is not torch.optim.RAdam:
            raise TypeError(f"FlatRAdam: needs a torch.optim.RAdam, got {type(optimizer)}")
        if len(optimizer.param_groups) != 1:
            raise ValueError(
                f"FlatRAdam: one parameter group only, got {len(optimizer.param_groups)}"
            )
        group = optimizer.param_groups[0]
        unsupported = {k: group.get(k) for k, v in SUPPORTED.items() if group.get(k, v) != v}
        if group.get("foreach"):  # torch's multi-tensor step rounds differently
            unsupported["foreach"] = group["foreach"]
        if unsupported:
            raise ValueError(f"FlatRAdam: RAdam settings not supported: {unsupported}")
        self.optimizer = optimizer
        self.group = group
        self.params: list[torch.Tensor] = list(group["params"])
        if any(p.is_complex() or p.dtype != self.params[0].dtype for p in self.params):
            dtypes = sorted({str(p.dtype) for p in self.params})
            raise ValueError(f"FlatRAdam: the parameters must be real and of one dtype: {dtypes}")
        if any(p.device.type != "cpu" for p in self.params):
            devices = sorted({str(p.device) for p in self.params})
            raise ValueError(f"FlatRAdam: CPU parameters only (flat CPU buffers), got {devices}")
        self.sizes = [p.numel() for p in self.params]
        total = sum(self.sizes)
        self.exp_avg = torch.zeros(total, dtype=self.params[0].dtype)
        self.exp_avg_sq = torch.zeros(total, dtype=self.params[0].dtype)
        steps = set()
        for p, avg, avg_sq in zip(self.params, *self._views(), strict=True):
            state = optimizer.state.get(p)
            if state:
                avg.copy_(state["exp_avg"])
                avg_sq.copy_(state["exp_avg_sq"])
                steps.add(float(state["step"]))
            else:
                steps.add(0.0)
        if len(steps) != 1:
            raise ValueError(f"FlatRAdam: the parameters have taken different steps: {steps}")
        self.step_count = steps.pop()
        self._grad = torch.empty(total, dtype=self.params[0].dtype)
        self._update = torch.empty(total, dtype=self.params[0].dtype)
        self._adaptive_lr = torch.empty(total, dtype=self.params[0].dtype)
        self._update_views = self._as_params(self._update)

    def _as_params(self, flat: torch.Tensor) -> list[torch.Tensor]:
        """Views of ``flat`` shaped as the parameters."""
        return [a.view_as(p) for a, p in zip(flat.split(self.sizes), self.params, strict=True)]

    def _views(self) -> tuple[list[torch.Tensor], list[torch.Tensor]]:
        return self._as_params(self.exp_avg), self._as_params(self.exp_avg_sq)

    @torch.no_grad()
    def step(self) -> None:
        """One RAdam step: ``torch.optim.radam._single_tensor_radam``'s operations, flat.

        Each out-of-place product of torch's step is computed in place into a buffer here
        (the same kernel and the same float32 scalar, so the same bits); ``c / t`` is
        ``t.reciprocal() * c``, as torch's ``Tensor.__rtruediv__`` computes it.
        """
        grads = [p.grad for p in self.params]
        missing = [f"#{i} {tuple(p.shape)}" for i, p in enumerate(self.params) if p.grad is None]
        if missing:
            raise RuntimeError(
                f"FlatRAdam: every parameter needs a gradient; none for {', '.join(missing)} "
                "(not used by the loss, or no backward call): torch.optim.RAdam would skip "
                "them, FlatRAdam steps every parameter"
            )
        group = self.group
        beta1, beta2 = group["betas"]
        lr, eps = float(group["lr"]), group["eps"]
        # torch counts steps in a float32 tensor and reads it back as a Python float
        self.step_count = float(torch.tensor(self.step_count + 1, dtype=torch.float32))
        step = self.step_count
        torch.cat([g.reshape(-1) for g in grads], out=self._grad)
        self.exp_avg.lerp_(self._grad, 1 - beta1)
        self.exp_avg_sq.mul_(beta2).addcmul_(self._grad, self._grad, value=1 - beta2)
        bias_correction1 = 1 - beta1**step
        bias_correction2 = 1 - beta2**step
        update = torch.div(self.exp_avg, bias_correction1, out=self._update)
        rho_inf = 2 / (1 - beta2) - 1
        rho_t = rho_inf - 2 * step * (beta2**step) / bias_correction2
        update.mul_(lr)
        if rho_t > RECTIFY_ABOVE:
            rect = (
                (rho_t - 4) * (rho_t - 2) * rho_inf / ((rho_inf - 4) * (rho_inf - 2) * rho_t)
            ) ** 0.5
            adaptive_lr = torch.sqrt(self.exp_avg_sq, out=self._adaptive_lr).add_(eps)
            adaptive_lr.reciprocal_().mul_(bias_correction2**0.5)
            update.mul_(adaptive_lr).mul_(rect)
        torch._foreach_add_(self.params, self._update_views, alpha=-1.0)

    def zero_grad(self) -> None:
        """The gradients set to ``None``, as the torch optimiser's ``zero_grad()`` does by
        default (without its hooks and profiler record: ~20 us a step less)."""
        for p in self.params:
            p.grad = None

    def store(self) -> None:
        """Write the moments and step counts into the torch optimiser's state (nothing
        before the first step: torch's RAdam has no state then either)."""
        if self.step_count == 0:
            return
        for p, avg, avg_sq in zip(self.params, *self._views(), strict=True):
            state = self.optimizer.state[p]
            if not state:
                state["step"] = torch.tensor(0.0)
                state["exp_avg"] = torch.zeros_like(p, memory_format=torch.preserve_format)
                state["exp_avg_sq"] = torch.zeros_like(p, memory_format=torch.preserve_format)
            state["step"].fill_(self.step_count)
            state["exp_avg"].copy_(avg)
            state["exp_avg_sq"].copy_(avg_sq)
