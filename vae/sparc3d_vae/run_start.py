"""What a training run starts from: a new run's settings (the jobs' measured ones, `--init-from`'s
model, `--config` on top) or a resumed run's (its checkpoint's, with what may change), the
command line's values over them, and the refusals that keep a resumed run the same run."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, List, NamedTuple, Optional, Tuple

from . import distributed, presets
from .config import Config, load_config
from .data import JobInfo, job_info
from .runtime import UsageError, checkpoint_path, config_diff, load_checkpoint

#: [train] keys that decide which batches a run sees and how it learns them: a resumed run
#: must keep them (the others, such as `steps`, `lr` or `checkpoint_every`, may change).
TRAJECTORY_KEYS = ("batch_size", "seed", "teacher_forcing", "structure", "augment_rotations",
                   "ema_decay", "hold_out", "hold_out_seed")


class InitWeights:
    """The weights a new run starts from (`--init-from`): another run's EMA weights (its raw
    weights when it kept no average), whatever resolution it was trained at: the sparse
    convolutions' kernels do not depend on the grid's size, so a model trained at 64³ is a
    starting point at 128³ (docs/VAE.md, "128³ on CPU")."""

    def __init__(self, path: Path, state: Dict[str, Any]):
        self.path = path
        self.config = Config.from_dict(state["config"], str(path))
        self.weights = state.get("ema") or state["model"]
        self.step = int(state.get("step", 0))
        self.resolutions = state.get("data", {}).get("resolutions")

    def record(self) -> Dict[str, Any]:
        """What the new run's checkpoint says about where it started."""
        return {"path": str(self.path), "step": self.step, "resolutions": self.resolutions,
                "weights_digest": distributed.weights_digest(self.weights)}


class RunStart(NamedTuple):
    """What a run starts from."""

    #: The checkpoint's state when resuming, else None.
    state: Optional[Dict[str, Any]]
    #: The `--init-from` weights of a new run, else None.
    init: Optional[InitWeights]
    #: The jobs.
    info: JobInfo
    #: The config in force.
    cfg: Config
    #: Where the config came from.
    settings: presets.Settings


def start_run(data: List[str], ckpt_path: Path, config: Optional[Path], resume: bool,
              init_from: Optional[Path], world: distributed.World) -> RunStart:
    """What a run starts from: a resumed run's checkpoint and config, or a new run's
    `--init-from` weights and settings; the jobs either way."""
    if resume and init_from is not None:
        raise UsageError("--init-from starts a new run from another's weights, --resume "
                         "continues this one: pass one of them")
    if resume:
        state = load_checkpoint(ckpt_path)
        cfg, settings = _resume_config(state, ckpt_path, config, world)
        return RunStart(state, None, job_info(data), cfg, settings)
    if ckpt_path.exists():
        raise UsageError(f"{ckpt_path.parent} already holds a checkpoint: pass --resume to "
                         "continue it, or choose another --out")
    init = None
    if init_from is not None:
        init_path = checkpoint_path(init_from)
        init = InitWeights(init_path, load_checkpoint(init_path))
    info = job_info(data)
    cfg, settings = _new_config(info.resolutions, config, init)
    return RunStart(None, init, info, cfg, settings)


def apply_options(start: RunStart, steps: Optional[int], seed: Optional[int],
                  hold_out: Optional[int], hold_out_seed: Optional[int]) -> None:
    """The command line's `--steps`, `--seed`, `--hold-out`, `--hold-out-seed` over the
    config's keys; a resumed run refuses another seed or hold-out than it started with."""
    cfg = start.cfg
    if steps is not None:
        cfg.train.steps = steps
    for flag, key, value in (("--seed", "seed", seed), ("--hold-out", "hold_out", hold_out),
                             ("--hold-out-seed", "hold_out_seed", hold_out_seed)):
        if value is None:
            continue
        if start.state is not None and value != getattr(cfg.train, key):
            raise UsageError(f"{flag} {value}: the run was started with train.{key} = "
                             f"{getattr(cfg.train, key)}")
        setattr(cfg.train, key, value)


def take_deformation(start: RunStart) -> None:
    """Sets the model's deformation to the data's: a checkpoint's or `--init-from`'s model
    trained the other way is refused."""
    cfg, info, init = start.cfg, start.info, start.init
    if (start.state is not None or init is not None) and cfg.model.deformation != info.deformation:
        whose = "the checkpoint's" if init is None else f"--init-from {init.path}: its"
        raise UsageError(f"{whose} model {'reads' if cfg.model.deformation else 'has no'} "
                         f"deformation, but the data {'has' if info.deformation else 'has none'}")
    cfg.model.deformation = info.deformation


def _asked_config(cfg: Config, config: Path, base_name: str) -> Tuple[Config, List[str]]:
    """`config`'s keys on top of `cfg` (called `base_name` in errors), keeping `cfg`'s
    deformation (which the data decides), and the [model] keys in which the result differs
    from `cfg` (dotted, with both values)."""
    asked = load_config(config, cfg, base_name)
    asked.model.deformation = cfg.model.deformation
    return asked, config_diff(cfg.to_dict()["model"], asked.to_dict()["model"], "model.")


def _resume_config(state: Dict[str, Any], ckpt_path: Path, config: Optional[Path],
                   world: distributed.World) -> Tuple[Config, presets.Settings]:
    """The config of a resumed run and where it came from: the checkpoint's, with the keys
    `config` sets on top when given. Refused, naming the keys: another [model], another value
    of a `TRAJECTORY_KEYS` key, another world size."""
    cfg = Config.from_dict(state["config"], str(ckpt_path))
    settings = presets.Settings.from_record(state.get("settings"))
    trained_world = int(state.get("world_size", 1))
    if trained_world != world.size:
        raise UsageError(f"{ckpt_path}: trained with world size {trained_world}, resumed with "
                         f"{world.size} (WORLD_SIZE; torchrun --nproc_per_node): the batches "
                         "would differ; resume with the same number of processes")
    if config is None:
        return cfg, settings
    asked, diff = _asked_config(cfg, config, f"the settings of {ckpt_path}")
    old_t, new_t = cfg.to_dict()["train"], asked.to_dict()["train"]
    diff += config_diff({k: old_t[k] for k in TRAJECTORY_KEYS},
                        {k: new_t[k] for k in TRAJECTORY_KEYS}, "train.")
    if diff:
        raise UsageError(f"{config}: differs from the checkpoint {ckpt_path} in "
                         f"{'; '.join(diff)} ([model] differs or the batches would); start a new "
                         "run with another --out")
    settings.configs.append(str(config))
    return asked, settings


def _new_config(resolutions: List[int], config: Optional[Path],
                init: Optional[InitWeights]) -> Tuple[Config, presets.Settings]:
    """The config of a new run and where it came from (`presets`): the measured settings for
    the jobs' `resolutions`, with the [model] of `init` when starting from its weights, then
    the keys `config` sets. With `init`, a [model] key of `config` that differs from its
    model is refused, naming the keys: the weights would not fit."""
    cfg, settings = presets.for_jobs(resolutions)
    if init is not None:
        cfg.model = init.config.model
        settings.model_from = str(init.path)
    if config is None:
        return cfg, settings
    asked, diff = _asked_config(cfg, config, settings.base())
    if init is not None and diff:
        raise UsageError(f"{config}: its [model] differs from the one of --init-from {init.path} "
                         f"in {'; '.join(diff)}: the weights would not fit")
    settings.configs.append(str(config))
    return asked, settings
