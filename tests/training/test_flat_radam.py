"""FlatRAdam: torch's RAdam step over all parameters at once, bit for bit."""

from __future__ import annotations

import io

import pytest
import torch

from pilerl.policies.attention import ANNet, DANNet
from pilerl.policies.controllers import NNetV2
from pilerl.training.flat_radam import FlatRAdam


def _train(
    controller,
    steps: int,
    *,
    flat: bool,
    dtype=torch.float32,
    resume_at: int = 0,
    from_torch_at: int = 0,
):
    """``steps`` RAdam steps on a fixed regression task; returns the weights, the losses and
    the optimiser's state dict. ``resume_at``: a new FlatRAdam is made from the torch
    optimiser's state at that step (as train_bc does after a resume). ``from_torch_at``:
    torch's RAdam steps until then, its state dict goes through ``torch.save`` into a fresh
    optimiser and FlatRAdam goes on from it (a checkpoint of the code before FlatRAdam)."""
    controller = controller.to(dtype).train()
    optimizer = torch.optim.RAdam(controller.parameters(), lr=1e-3)
    step = FlatRAdam(optimizer) if flat and not from_torch_at else optimizer
    generator = torch.Generator().manual_seed(1)
    losses = []
    torch.manual_seed(2)  # the dropout draws
    for i in range(steps):
        if flat and i == resume_at and i > 0:
            step.store()
            step = FlatRAdam(optimizer)
        if flat and i == from_torch_at and i > 0:
            buffer = io.BytesIO()
            torch.save(optimizer.state_dict(), buffer)
            buffer.seek(0)
            optimizer = torch.optim.RAdam(controller.parameters(), lr=1e-3)
            optimizer.load_state_dict(torch.load(buffer))
            step = FlatRAdam(optimizer)
        s = torch.randn(37, 4, generator=generator, dtype=dtype)
        target = torch.tanh(s[:, :3].sum(-1, keepdim=True)).expand(37, 3)
        loss = ((controller(s).action - target) ** 2).mean()
        step.zero_grad()
        loss.backward()
        step.step()
        losses.append(float(loss.detach()))
    if flat:
        step.store()
    return controller.state_dict(), losses, optimizer.state_dict()


def _equal_state(a: dict, b: dict) -> bool:
    return a["param_groups"] == b["param_groups"] and all(
        torch.equal(x[key], y[key])
        for x, y in zip(a["state"].values(), b["state"].values(), strict=True)
        for key in x
    )


@pytest.mark.parametrize("controller_class", [NNetV2, ANNet, DANNet])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_flat_radam_steps_as_torch_radam_bit_for_bit(controller_class, dtype):
    """Every gradient-trained controller, in float32 and float64, over the first steps
    (rho_t <= 5, no adaptive rate) and many after: equal losses, weights and state."""

    def controller():
        torch.manual_seed(0)
        return controller_class(4)

    weights, losses, state = _train(controller(), 60, flat=False, dtype=dtype)
    flat_weights, flat_losses, flat_state = _train(controller(), 60, flat=True, dtype=dtype)
    assert flat_losses == losses
    assert all(torch.equal(weights[k], flat_weights[k]) for k in weights)
    assert _equal_state(state, flat_state)
    assert float(state["state"][0]["step"]) == 60


def test_flat_radam_made_from_a_saved_state_goes_on_the_same_way():
    """A FlatRAdam made from a torch optimiser that has taken steps (a resumed run) reads
    its moments and step count."""
    torch.manual_seed(0)
    weights, losses, state = _train(NNetV2(4), 20, flat=False)
    torch.manual_seed(0)
    resumed, resumed_losses, resumed_state = _train(NNetV2(4), 20, flat=True, resume_at=9)
    assert resumed_losses == losses
    assert all(torch.equal(weights[k], resumed[k]) for k in weights)
    assert _equal_state(state, resumed_state)


def test_flat_radam_refuses_what_it_does_not_compute():
    model = NNetV2(4)
    with pytest.raises(ValueError, match="not supported: {'weight_decay': 0.1}"):
        FlatRAdam(torch.optim.RAdam(model.parameters(), weight_decay=0.1))
    with pytest.raises(TypeError, match="needs a torch.optim.RAdam"):
        FlatRAdam(torch.optim.Adam(model.parameters()))
    optimizer = FlatRAdam(torch.optim.RAdam(model.parameters()))
    with pytest.raises(RuntimeError, match="every parameter needs a gradient"):
        optimizer.step()  # no backward yet: torch would skip them silently
    untouched = torch.optim.RAdam(model.parameters())
    FlatRAdam(untouched).store()  # no step taken: no state, as torch's
    assert untouched.state_dict()["state"] == {}


def test_flat_radam_goes_on_from_a_torch_radam_checkpoint():
    """A run checkpointed by torch's RAdam (the code before FlatRAdam), saved, loaded into a
    new optimiser and resumed with FlatRAdam trains as torch's RAdam would have."""
    torch.manual_seed(0)
    weights, losses, _ = _train(DANNet(4), 30, flat=False)
    torch.manual_seed(0)
    resumed, resumed_losses, _ = _train(DANNet(4), 30, flat=True, from_torch_at=9)
    assert resumed_losses == losses
    assert all(torch.equal(weights[k], resumed[k]) for k in weights)
