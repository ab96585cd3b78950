"""sparc3d-vae: Sparconv-VAE (paper Sparc3D §3.5) on sparc3d shards, in plain PyTorch.

    from sparc3d_vae.sparse import SparseTensor          # coords int32 [N, 4] + feats [N, C]
    from sparc3d_vae.ops import SubmConv3d, DownConv3d, SubdivideConv3d
    from sparc3d_vae.model import SparconvVAE
    from sparc3d_vae.config import Config, load_config
    from sparc3d_vae.presets import for_jobs             # the settings `train` takes for a job

Commands: `sparc3d-vae train | encode | decode | reconstruct | evaluate` (or
`python -m sparc3d_vae ...`); docs/VAE.md describes the model, the loss and the measurements.
"""

__version__ = "0.1.0"
