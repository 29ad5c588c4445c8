//! Work shared out over a cluster's batch scheduler (docs/cluster.md):
//! images rendered in bands ([`tiles`]) and the Slurm job scripts of a
//! sweep ([`slurm`]). Slurm does the distribution; this module only makes
//! the work shardable and mergeable and writes the scripts.

pub mod slurm;
pub mod tiles;
