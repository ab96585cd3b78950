"""`EMA`: the exponential moving average of a model's weights that training keeps beside them."""

from __future__ import annotations

from typing import Dict

import torch


class EMA:
    """Exponential moving average of the weights (float32), what inference loads when the
    checkpoint holds it: w̄ ← d·w̄ + (1 − d)·w after every step, with d = min(decay,
    (1 + step) / (10 + step)) so early weights fade fast (the warm-up of TensorFlow's
    `ExponentialMovingAverage(num_updates=...)`). TRELLIS evaluates its VAEs with an EMA too."""

    def __init__(self, model: torch.nn.Module, decay: float):
        self.model = model
        self.decay = decay
        self.shadow = {k: v.detach().float().clone() for k, v in model.state_dict().items()}

    @torch.no_grad()
    def update(self, step: int) -> None:
        """Moves the average towards the model's weights after step `step`."""
        d = min(self.decay, (1 + step) / (10 + step))
        for k, v in self.model.state_dict().items():
            self.shadow[k].mul_(d).add_(v.detach().float(), alpha=1 - d)

    def state_dict(self) -> Dict[str, torch.Tensor]:
        """A copy of the averaged weights, as a model's `state_dict`."""
        return {k: v.clone() for k, v in self.shadow.items()}

    def load(self, state: Dict[str, torch.Tensor]) -> None:
        """Takes the averaged weights of a checkpoint (float32, on the model's device)."""
        self.shadow = {k: v.detach().float().clone().to(self.shadow[k].device) for k, v in state.items()}
