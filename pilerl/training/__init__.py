"""Training: behaviour cloning of one controller or a seed ensemble (RL is in pilerl.rl)."""

from .bc import BCSettings, epochs_for_steps, train_bc, validation_loss
from .ensemble import EnsembleResult, train_bc_ensemble, write_ensemble_curves

__all__ = [
    "BCSettings",
    "EnsembleResult",
    "epochs_for_steps",
    "train_bc",
    "train_bc_ensemble",
    "validation_loss",
    "write_ensemble_curves",
]
