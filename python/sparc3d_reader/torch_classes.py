"""The reader's datasets as torch classes, made on first use so that importing the package never
imports torch."""

from typing import Dict, Tuple

_made: Dict[str, type] = {}


def torch_class(name: str, base: type, torch_base: str, module: str) -> type:
    """Class `name`: `base`, with `torch.utils.data.<torch_base>` as a second base when torch
    imports (`base` alone when it does not); `module` is where pickle finds it (the package,
    which makes it on first access too)."""
    if name not in _made:
        try:
            import torch.utils.data as tud

            bases: Tuple[type, ...] = (base, getattr(tud, torch_base))
        except ImportError:
            bases = (base,)
        _made[name] = type(name, bases, {"__doc__": base.__doc__, "__module__": module})
    return _made[name]
