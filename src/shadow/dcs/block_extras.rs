//! The unbounded edges of a block of receivers, made in lanes: what the
//! receiver stage reads and the lane kernels (`edge_lanes`) write, in a
//! leaf so that neither imports the other both ways.

use super::counters::OrientedEdge;

/// One receiver's share of [`BlockExtras`].
#[derive(Debug, Clone, Copy)]
pub(super) struct MadeExtras<'a> {
    /// The effective edges among them, in id order.
    pub(super) effective: &'a [(OrientedEdge, i32)],
    /// Whether one's quad plane lies between the raster's receiver and
    /// `p'` (its start count is then recounted).
    pub(super) recount: bool,
    /// How many reached the receiver.
    pub(super) admitted: usize,
}

/// The unbounded edges of a 4² block's receivers ([`BLOCK`] of them,
/// row by row), made in lanes ([`LightPass::block_extras`](super::receiver::LightPass::block_extras)).
#[derive(Debug, Default)]
pub(super) struct BlockExtras {
    pub(super) effective: [Vec<(OrientedEdge, i32)>; BLOCK],
    pub(super) recount: [bool; BLOCK],
    pub(super) admitted: [usize; BLOCK],
}

/// Receivers of a block.
pub(super) const BLOCK: usize = 16;

impl BlockExtras {
    /// Block receiver `k`'s share.
    pub(super) fn of(&self, k: usize) -> MadeExtras<'_> {
        MadeExtras {
            effective: &self.effective[k],
            recount: self.recount[k],
            admitted: self.admitted[k],
        }
    }
}
