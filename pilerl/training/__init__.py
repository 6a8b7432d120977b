"""Training: behaviour cloning (more learners come with the RL recipes)."""

from .bc import BCSettings, train_bc, validation_loss

__all__ = ["BCSettings", "train_bc", "validation_loss"]
