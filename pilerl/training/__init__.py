"""Training: behaviour cloning (more learners come with the RL recipes)."""

from .bc import BCSettings, train_bc, validation_loss
from .ensemble import EnsembleResult, train_bc_ensemble

__all__ = ["BCSettings", "EnsembleResult", "train_bc", "train_bc_ensemble", "validation_loss"]
