"""Levenberg-Marquardt training for small networks (NNet, as Halbach et al. trained it).

Each iteration linearises the residuals r(theta) = F(s; theta) - u around the current
parameters and solves the damped Gauss-Newton system

    (J^T J + mu I) delta = -J^T r

where J [N * n_u, P] is the Jacobian of the residuals with respect to the P flattened
parameters, computed with ``torch.func`` (``functional_call`` + ``jacfwd`` by default:
one forward-mode pass per parameter, cheap because LM's networks have tens of
parameters; ``jacrev`` is the choice when the batch is smaller than P). A step is kept
only if it lowers the loss; the damping follows MATLAB's ``trainlm``: mu starts at 1e-3,
is multiplied by ``mu_dec`` = 0.1 after an accepted step and by ``mu_inc`` = 10 after a
rejected one, and training stops when mu exceeds ``mu_max`` = 1e10.

P x P systems are solved in float64; memory grows as N * n_u * P, so large datasets use
mini-batches (``batch_size``), each iteration drawing a fresh one.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import nn
from torch.func import functional_call, jacfwd, jacrev

MU_INIT = 1e-3  # MATLAB trainlm defaults
MU_DEC = 0.1
MU_INC = 10.0
MU_MAX = 1e10
MU_MIN = 1e-20  # keeps mu from underflowing after many accepted steps
JACOBIANS = {"forward": jacfwd, "reverse": jacrev}


def fit_lm(
    model: nn.Module,
    inputs: torch.Tensor,
    targets: torch.Tensor,
    *,
    iterations: int,
    batch_size: int | None = None,
    mu: float = MU_INIT,
    mu_dec: float = MU_DEC,
    mu_inc: float = MU_INC,
    mu_max: float = MU_MAX,
    jacobian: str = "forward",
    generator: torch.Generator | None = None,
) -> list[float]:
    """Fit ``model`` (in place) so that ``model(inputs)`` matches ``targets`` (MSE).

    Args:
        model: maps inputs [N, n_in] to predictions [N, n_out], or to a tuple whose first
            element is the prediction (controllers return ``ControllerOutput``). It is
            evaluated in eval mode (no dropout) and put back in its previous mode.
        iterations: accepted-or-final LM steps (one Jacobian each).
        batch_size: rows per iteration, drawn at random with ``generator``; ``None``
            uses all rows (full-batch LM, as MATLAB).
        mu, mu_dec, mu_inc, mu_max: damping schedule (MATLAB trainlm's defaults).
        jacobian: ``forward`` (``jacfwd``) or ``reverse`` (``jacrev``).

    Returns:
        The MSE on each iteration's batch after its step (shorter than ``iterations`` if
        mu exceeded ``mu_max``, i.e. no step could lower the loss).
    """
    if jacobian not in JACOBIANS:
        raise ValueError(f"unknown jacobian {jacobian!r}; known: {sorted(JACOBIANS)}")
    if inputs.shape[0] != targets.shape[0]:
        raise ValueError(f"{inputs.shape[0]} inputs but {targets.shape[0]} targets")
    names = [n for n, p in model.named_parameters() if p.requires_grad]
    params = [p for p in model.parameters() if p.requires_grad]
    shapes = [p.shape for p in params]
    sizes = [p.numel() for p in params]
    flat = torch.cat([p.detach().reshape(-1) for p in params])
    n_rows = inputs.shape[0]
    was_training = model.training
    model.eval()

    def unflatten(vector: torch.Tensor) -> dict[str, torch.Tensor]:
        parts = vector.split(sizes)
        return {n: v.reshape(s) for n, v, s in zip(names, parts, shapes, strict=True)}

    def residual_fn(x: torch.Tensor, y: torch.Tensor) -> Callable:
        def residuals(vector: torch.Tensor) -> torch.Tensor:
            out = functional_call(model, unflatten(vector), (x,))
            prediction = out[0] if isinstance(out, tuple) else out
            return (prediction - y).reshape(-1)

        return residuals

    history: list[float] = []
    try:
        for _ in range(iterations):
            if batch_size is None or batch_size >= n_rows:
                x, y = inputs, targets
            else:
                rows = torch.randperm(n_rows, generator=generator)[:batch_size]
                x, y = inputs[rows], targets[rows]
            residuals = residual_fn(x, y)
            with torch.no_grad():
                r = residuals(flat)
                loss = float(r.square().mean())
            jac = JACOBIANS[jacobian](residuals)(flat).double()  # [N * n_out, P]
            jtj = jac.T @ jac
            gradient = jac.T @ r.double()
            eye = torch.eye(flat.numel(), dtype=torch.float64, device=flat.device)
            while True:
                step = torch.linalg.solve(jtj + mu * eye, -gradient)
                candidate = flat + step.to(flat.dtype)
                with torch.no_grad():
                    new_loss = float(residuals(candidate).square().mean())
                if new_loss < loss:
                    flat, loss = candidate, new_loss
                    mu = max(mu * mu_dec, MU_MIN)
                    break
                mu *= mu_inc
                if mu > mu_max:
                    break
            history.append(loss)
            if mu > mu_max:
                break
    finally:
        with torch.no_grad():
            for p, value in zip(params, flat.split(sizes), strict=True):
                p.copy_(value.reshape(p.shape))
        model.train(was_training)
    return history
