"""Random-forest controller (Yang et al. 2020, ICRA): 20 regression trees of depth <= 30.

scikit-learn's ``RandomForestRegressor`` fits the forest; the fitted trees are then copied
into tensors (child indices, split feature, threshold, leaf values) and evaluated in
torch. So the forest

- acts through the same interface as the neural controllers (an ``nn.Module`` in a
  ``TensorDictModule``), batched or not;
- is saved in the same ``state_dict`` checkpoint as them, loaded with
  ``torch.load(weights_only=True)``: no pickle, so loading a file cannot run code
  (a scikit-learn model saved with pickle/joblib could);
- predicts exactly what scikit-learn predicts (the split test is done in float64 on the
  float32 input, as scikit-learn does; leaf values are kept in float32).

It is not differentiable and has no pre-tanh output: it cannot sit in the stochastic
wrapper for policy-gradient fine-tuning.
"""

from __future__ import annotations

import numpy as np
import torch

from .controllers import Controller, ControllerOutput

N_ESTIMATORS = 20  # Yang et al. 2020 / revised paper
MAX_DEPTH = 30
MAX_TREE_DEPTH = 512  # a loaded forest deeper than this is refused (acting loops per level)
SEED = 0
TREE_BUFFERS = ("children_left", "children_right", "feature", "threshold", "value")
TREE_DTYPES = {
    "children_left": torch.int32,
    "children_right": torch.int32,
    "feature": torch.int32,
    "threshold": torch.float64,
    "value": torch.float32,
    "depth": torch.int64,
}


class RandomForestController(Controller):
    """A fitted forest as tensors; ``fit`` first, then ``forward(s)``.

    Buffers (T trees padded to the largest node count N):
        children_left, children_right: [T, N] int32; a leaf points to itself.
        feature: [T, N] int32, split feature (0 at leaves).
        threshold: [T, N] float64, go left when ``s[feature] <= threshold`` (+inf at leaves).
        value: [T, N, n_u] float32, leaf prediction.
        depth: [] int64, number of traversal steps (the deepest tree's depth).
    """

    has_pre_tanh = False
    differentiable = False

    children_left: torch.Tensor
    children_right: torch.Tensor
    feature: torch.Tensor
    threshold: torch.Tensor
    value: torch.Tensor
    depth: torch.Tensor

    def __init__(
        self,
        n_inputs: int,
        n_controls: int = 3,
        *,
        n_estimators: int = N_ESTIMATORS,
        max_depth: int | None = MAX_DEPTH,
        seed: int = SEED,
        min_samples_leaf: int = 1,
        n_jobs: int | None = None,
    ) -> None:
        super().__init__()
        self.n_inputs, self.n_controls = n_inputs, n_controls
        self.forest_kwargs = {
            "n_estimators": n_estimators,
            "max_depth": max_depth,
            "random_state": seed,
            "min_samples_leaf": min_samples_leaf,
            "n_jobs": n_jobs,
        }
        self.register_buffer("children_left", torch.zeros(0, 0, dtype=torch.int32))
        self.register_buffer("children_right", torch.zeros(0, 0, dtype=torch.int32))
        self.register_buffer("feature", torch.zeros(0, 0, dtype=torch.int32))
        self.register_buffer("threshold", torch.zeros(0, 0, dtype=torch.float64))
        self.register_buffer("value", torch.zeros(0, 0, n_controls, dtype=torch.float32))
        self.register_buffer("depth", torch.zeros((), dtype=torch.int64))

    @property
    def fitted(self) -> bool:
        return self.threshold.numel() > 0

    def fit(self, s: torch.Tensor, action: torch.Tensor) -> RandomForestController:
        """Fit the forest on inputs ``s`` [N, n_s] and actions [N, n_u] (seeded)."""
        from sklearn.ensemble import RandomForestRegressor  # slow import, fitting only

        if s.ndim != 2 or s.shape[-1] != self.n_inputs:
            raise ValueError(f"fit: s must be [N, {self.n_inputs}], got {tuple(s.shape)}")
        if action.shape != (s.shape[0], self.n_controls):
            raise ValueError(
                f"fit: action must be [{s.shape[0]}, {self.n_controls}], got {tuple(action.shape)}"
            )
        inputs = s.detach().cpu().numpy().astype(np.float32)
        targets = action.detach().cpu().numpy().astype(np.float64)
        forest = RandomForestRegressor(**self.forest_kwargs).fit(inputs, targets)
        self.load_forest(forest)
        return self

    def load_forest(self, forest) -> None:
        """Copy a fitted scikit-learn ``RandomForestRegressor``'s trees into the buffers."""
        trees = [estimator.tree_ for estimator in forest.estimators_]
        n_nodes = max(tree.node_count for tree in trees)
        shape = (len(trees), n_nodes)
        own = np.broadcast_to(np.arange(n_nodes), shape)
        left, right = own.copy(), own.copy()  # padding and leaves point to themselves
        feature = np.zeros(shape, dtype=np.int64)
        threshold = np.full(shape, np.inf)
        value = np.zeros((*shape, self.n_controls))
        for t, tree in enumerate(trees):
            n = tree.node_count
            split = tree.children_left >= 0  # sklearn marks leaves with -1
            left[t, :n] = np.where(split, tree.children_left, np.arange(n))
            right[t, :n] = np.where(split, tree.children_right, np.arange(n))
            feature[t, :n] = np.where(split, tree.feature, 0)
            threshold[t, :n] = np.where(split, tree.threshold, np.inf)
            value[t, :n] = tree.value.reshape(n, -1)
        self.children_left = torch.as_tensor(left, dtype=torch.int32)
        self.children_right = torch.as_tensor(right, dtype=torch.int32)
        self.feature = torch.as_tensor(feature, dtype=torch.int32)
        self.threshold = torch.as_tensor(threshold, dtype=torch.float64)
        self.value = torch.as_tensor(value, dtype=torch.float32)
        self.depth = torch.tensor(max(tree.max_depth for tree in trees), dtype=torch.int64)

    def forward(self, s: torch.Tensor, s_att: torch.Tensor | None = None) -> ControllerOutput:
        if not self.fitted:
            raise RuntimeError("RandomForestController: call fit(...) before acting")
        batch_shape = s.shape[:-1]
        x = s.reshape(-1, self.n_inputs).double()
        n_trees, n_nodes = self.threshold.shape
        offset = torch.arange(n_trees, device=s.device) * n_nodes  # [T]
        node = torch.zeros(x.shape[0], n_trees, dtype=torch.long, device=s.device)
        left, right = self.children_left.reshape(-1), self.children_right.reshape(-1)
        feature, threshold = self.feature.reshape(-1), self.threshold.reshape(-1)
        for _ in range(int(self.depth)):
            flat = node + offset
            go_left = x.gather(1, feature[flat].long()) <= threshold[flat]
            node = torch.where(go_left, left[flat], right[flat]).long()
        leaves = self.value.reshape(-1, self.n_controls)[node + offset]  # [B, T, n_u]
        action = leaves.mean(1).clamp(-1.0, 1.0).to(s.dtype)
        return ControllerOutput(action.reshape(*batch_shape, self.n_controls))

    def _load_from_state_dict(
        self, state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, errors
    ) -> None:
        # the forest's size is known only from the checkpoint: check its trees, then
        # resize the buffers before copying
        saved = {name: state_dict.get(prefix + name) for name in (*TREE_BUFFERS, "depth")}
        if all(isinstance(t, torch.Tensor) for t in saved.values()):
            try:
                check_forest(saved, n_inputs=self.n_inputs, n_controls=self.n_controls)
            except ValueError as error:
                errors.append(f"random forest: {error}")
                return
            for name in TREE_BUFFERS:
                setattr(self, name, torch.empty_like(saved[name], device="cpu"))
        super()._load_from_state_dict(
            state_dict, prefix, local_metadata, strict, missing_keys, unexpected_keys, errors
        )

    def extra_repr(self) -> str:
        size = f"{self.threshold.shape[0]} trees" if self.fitted else "not fitted"
        return f"n_inputs={self.n_inputs}, n_controls={self.n_controls}, {size}"


def check_forest(buffers: dict[str, torch.Tensor], *, n_inputs: int, n_controls: int) -> None:
    """Raise ``ValueError`` unless ``buffers`` (a saved forest) are trees that acting can use.

    Checks dtypes and shapes ([T, N] for children, feature and threshold, [T, N, n_u] for
    value, [] for depth), child indices within [0, N), split features within
    [0, n_inputs), that each tree seen from its root is a tree (every internal node has
    two children other than itself, no node is reached twice: no cycle), and that the
    saved ``depth`` (the number of steps ``forward`` takes) is the trees' real depth, at
    most ``MAX_TREE_DEPTH``. The walk is level by level, O(T * N).
    """
    for name, dtype in TREE_DTYPES.items():
        if buffers[name].dtype != dtype:
            raise ValueError(f"{name} is {buffers[name].dtype}, expected {dtype}")
    left, right = buffers["children_left"], buffers["children_right"]
    if left.dim() != 2:
        raise ValueError(f"children_left has shape {tuple(left.shape)}, expected [trees, nodes]")
    n_trees, n_nodes = left.shape
    for name in ("children_right", "feature", "threshold"):
        if buffers[name].shape != left.shape:
            raise ValueError(
                f"{name} has shape {tuple(buffers[name].shape)}, not {tuple(left.shape)}"
            )
    if buffers["value"].shape != (n_trees, n_nodes, n_controls):
        raise ValueError(
            f"value has shape {tuple(buffers['value'].shape)}, expected "
            f"{(n_trees, n_nodes, n_controls)}"
        )
    if buffers["depth"].dim() != 0:
        raise ValueError("depth is not a scalar")
    depth = int(buffers["depth"])
    if n_trees == 0 or n_nodes == 0:
        if depth != 0:
            raise ValueError(f"an empty forest with depth {depth}")
        return
    left, right = left.numpy().astype(np.int64), right.numpy().astype(np.int64)
    feature = buffers["feature"].numpy()
    for name, index, bound in (
        ("children_left", left, n_nodes),
        ("children_right", right, n_nodes),
        ("feature", feature, n_inputs),
    ):
        if index.min() < 0 or index.max() >= bound:
            raise ValueError(f"{name} holds indices outside [0, {bound})")
    own = np.arange(n_nodes)
    leaf = (left == own) & (right == own)
    split = ~leaf
    if ((left == own) | (right == own) | (left == right))[split].any():
        raise ValueError("a split node points to itself or twice to one child")
    reached = np.zeros((n_trees, n_nodes), dtype=bool)
    trees, nodes = np.arange(n_trees), np.zeros(n_trees, dtype=np.int64)
    levels = 0
    while True:
        if reached[trees, nodes].any() or len(np.unique(trees * n_nodes + nodes)) < len(nodes):
            raise ValueError("a node is reached twice: the trees have a cycle or shared nodes")
        reached[trees, nodes] = True
        inner = split[trees, nodes]
        if not inner.any():
            break
        levels += 1
        if levels > MAX_TREE_DEPTH:
            raise ValueError(f"a tree is deeper than {MAX_TREE_DEPTH} levels")
        trees, nodes = (
            np.concatenate([trees[inner], trees[inner]]),
            np.concatenate([left[trees[inner], nodes[inner]], right[trees[inner], nodes[inner]]]),
        )
    if depth != levels:
        raise ValueError(f"depth is {depth}, but the deepest tree has {levels} levels")
