"""Packed dropout masks: the distribution torch's dropout draws, from fewer random words."""

from __future__ import annotations

import pytest
import torch
import torch.nn.functional as F
from torch import nn

from pilerl.training.draw_ahead import masks_ahead
from pilerl.training.dropout_masks import (
    GivenMaskDropout,
    PackedDropout,
    dropout_masks,
    packed_keep_masks,
)

ROWS, COLUMNS = 1000, 1000  # a million elements: a keep rate to within ~5e-4


def test_packed_masks_keep_each_element_independently_with_probability_q():
    torch.manual_seed(0)
    p = 0.35
    mask = packed_keep_masks([(ROWS, COLUMNS)], p)[0]
    torch_scale = F.dropout(torch.ones(10_000), p, training=True).max()  # 1/q as torch has it
    assert set(mask.unique().tolist()) == {0.0, torch_scale.item()}
    kept = (mask > 0).double().flatten()
    q = round(0.65 * 2**16) / 2**16  # the keep probability (0.6499939)
    sigma = (q * (1 - q) / kept.numel()) ** 0.5
    assert abs(kept.mean().item() - q) < 5 * sigma
    # every 16-bit lane of a word keeps at that rate (the default int64 range of random_
    # would leave the last lane's top bit 0 and keep only 30% there)
    lanes = kept.view(-1, 4).mean(0)
    assert ((lanes - q).abs() < 5 * 2 * sigma).all(), lanes
    # neighbours (same word and across words) and rows are uncorrelated
    centred = kept - kept.mean()
    for lag in (1, 4, COLUMNS):
        correlation = (centred[:-lag] * centred[lag:]).mean() / centred.var()
        assert abs(correlation.item()) < 5 / kept.numel() ** 0.5, lag


def test_packed_masks_draw_from_the_global_generator_and_split_one_draw():
    torch.manual_seed(3)
    a, b = packed_keep_masks([(7, 5), (3,)], 0.5)
    torch.manual_seed(3)
    (both,) = packed_keep_masks([(38,)], 0.5)
    assert torch.equal(torch.cat([a.flatten(), b]), both)
    assert a.shape == (7, 5) and b.shape == (3,)
    after = torch.get_rng_state()
    torch.manual_seed(3)
    torch.empty(10, dtype=torch.int64).random_(-(2**63), None)  # ceil(38 / 4) words
    assert torch.equal(torch.get_rng_state(), after)


def test_packed_masks_edge_probabilities_and_bad_ones():
    state = torch.get_rng_state()
    assert torch.equal(packed_keep_masks([(4, 4)], 0.0)[0], torch.ones(4, 4))
    assert torch.equal(torch.get_rng_state(), state)  # p = 0 draws nothing, as torch
    assert torch.equal(packed_keep_masks([(4, 4)], 1.0)[0], torch.zeros(4, 4))
    with pytest.raises(ValueError, match=r"drop probability must be in \[0, 1\], got 1.5"):
        packed_keep_masks([(2,)], 1.5)


def test_dropout_masks_swap_the_layers_and_put_them_back():
    model = nn.Sequential(nn.Linear(3, 8), nn.Dropout(0.35), nn.Linear(8, 2), nn.Dropout(0.1))
    originals = [model[1], model[3]]
    x = torch.ones(64, 3)
    model.eval()
    with dropout_masks(model, "packed"):
        assert isinstance(model[1], PackedDropout) and model[3].p == 0.1
        assert not model[1].training  # the replaced layer's mode is kept
        assert torch.equal(model(x), model[2](model[0](x)))  # eval: no dropout
        model.train()
        torch.manual_seed(1)
        hidden = model[0](x)
        torch.manual_seed(1)
        mask = packed_keep_masks([hidden.shape], 0.35)[0]
        torch.manual_seed(1)
        assert torch.equal(model[1](hidden), hidden * mask)
    assert [model[1], model[3]] == originals
    with dropout_masks(model, "bernoulli"):
        assert model[1] is originals[0]
    with (
        pytest.raises(ValueError, match=r"dropout_masks: unknown 'fast'; known"),
        dropout_masks(model, "fast"),
    ):
        pass


def test_masks_drawn_ahead_are_torchs_draws_in_order():
    def model() -> nn.Sequential:
        torch.manual_seed(0)
        return nn.Sequential(nn.Linear(3, 8), nn.Dropout(0.35), nn.Linear(8, 5), nn.Dropout(0.5))

    rows = [7, 7, 3]  # a short last batch
    inputs = [torch.randn(n, 3) for n in rows]
    reference = model().train()
    torch.manual_seed(4)
    expected = [reference(x) for x in inputs]
    expected_state = torch.get_rng_state()

    ahead = model().train()
    with masks_ahead(ahead, lambda: ahead(inputs[0][:1])) as feed:
        assert feed is not None
        assert [(site.p, site.shape) for site in feed.layers] == [(0.35, (8,)), (0.5, (5,))]
        torch.manual_seed(4)
        feed.start_epoch(rows)
        for x, want in zip(inputs, expected, strict=True):
            feed.next_step()
            assert torch.equal(ahead(x), want)
        feed.end_epoch()
        assert torch.equal(torch.get_rng_state(), expected_state)
        feed.start_epoch([2])
        feed.next_step()
        with pytest.raises(RuntimeError, match=r"drawn for dropout layer 0, which got \(7, 8\)"):
            ahead(inputs[0])
    assert [type(m) for m in ahead] == [nn.Linear, nn.Dropout, nn.Linear, nn.Dropout]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_masks_drawn_ahead_have_the_dtype_and_device_torchs_dropout_uses(dtype):
    """torch's dropout draws ``empty_like(x)``: a float64 input gets a float64 mask (its
    scale 1/q rounded in float64), a float32 one float32; the masks drawn ahead are the
    same, so the outputs are bit-identical in both."""

    def model() -> nn.Sequential:
        torch.manual_seed(0)
        layers = nn.Sequential(nn.Linear(3, 8), nn.Dropout(0.35), nn.Linear(8, 5), nn.Dropout(0))
        return layers.to(dtype).train()

    x = torch.randn(6, 3, dtype=dtype)
    reference = model()
    torch.manual_seed(2)
    expected = reference(x)
    ahead = model()
    with masks_ahead(ahead, lambda: ahead(x[:1])) as feed:
        assert isinstance(ahead[3], nn.Dropout)  # p = 0: torch draws nothing, left alone
        torch.manual_seed(2)
        feed.start_epoch([6])
        feed.next_step()
        (mask,) = feed.current
        assert (mask.dtype, mask.device) == (x.dtype, x.device)
        assert torch.equal(ahead(x), expected)
        feed.end_epoch()
        feed.start_epoch([6])
        feed.next_step()
        with pytest.raises(RuntimeError, match=r"mask on cpu was drawn for dropout layer 0"):
            ahead[1](torch.ones(6, 8, dtype=torch.float16))
    no_dropout = nn.Sequential(nn.Linear(3, 2), nn.Dropout(0.0))
    with masks_ahead(no_dropout, lambda: no_dropout(torch.ones(1, 3))) as feed:
        assert feed is None  # nothing to draw ahead


def test_masks_drawn_ahead_refuse_a_non_contiguous_input():
    """torch draws into ``empty_like(x)``, which keeps a transposed input's column order:
    the same generator then fills other elements than a mask drawn ahead (contiguous), so
    such an input is refused instead of silently training on other masks."""
    torch.manual_seed(0)
    layers = nn.Sequential(nn.Linear(3, 8), nn.Dropout(0.35)).train()
    x = torch.randn(6, 3)
    transposed = torch.randn(8, 6).t()  # (6, 8), column-major
    torch.manual_seed(2)
    torch_mask = torch.nn.functional.dropout(torch.ones_like(transposed), 0.35)
    with masks_ahead(layers, lambda: layers(x[:1])) as feed:
        torch.manual_seed(2)
        feed.start_epoch([6])
        feed.next_step()
        (mask,) = feed.current
        assert not torch.equal(mask, torch_mask)  # why: another element order
        assert torch.equal(layers[1](transposed.contiguous()), transposed * mask)
        with pytest.raises(RuntimeError, match=r"layer 0 got a non-contiguous input"):
            layers[1](transposed)
        feed.end_epoch()


def test_given_mask_dropout_refuses_a_mask_of_another_shape():
    """The mask is one multiplier per element: a mask that would broadcast (one row for a
    batch, or a member's mask against another width) is refused, naming both shapes, also
    inside ``vmap`` as the ensemble calls it."""
    layer = GivenMaskDropout(0.5).train()
    x = torch.arange(12.0).view(4, 3)
    layer.mask = torch.tensor([2.0, 0.0, 2.0]).expand(4, 3).clone()
    assert torch.equal(layer(x), x * layer.mask)
    layer.mask = torch.tensor([[2.0, 0.0, 2.0]])
    with pytest.raises(ValueError, match=r"mask has shape \(1, 3\), the input \(4, 3\)"):
        layer(x)

    def member(mask: torch.Tensor) -> torch.Tensor:
        return torch.func.functional_call(layer, {"mask": mask}, (x,))

    members = torch.func.vmap(member, randomness="different")
    assert members(torch.ones(2, 4, 3)).shape == (2, 4, 3)
    with pytest.raises(ValueError, match=r"mask has shape \(4, 1\), the input \(4, 3\)"):
        members(torch.ones(2, 4, 1))
