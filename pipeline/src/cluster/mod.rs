//! Running a job on a cluster scheduler. Only Slurm needs code here (`sparc3d submit slurm`
//! and the Slurm section of `sparc3d status`); Kubernetes indexed Jobs and Ray drive
//! `sparc3d work` directly (see `ops/k8s/` and `ops/ray/`).

pub mod slurm;
pub mod slurm_submit;
