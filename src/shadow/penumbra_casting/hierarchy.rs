//! The receiver-point hierarchy (§3.2): an AABB tree over the receivers'
//! shadow-ray origins. Above [`SPATIAL_ABOVE`] points a node's box is
//! split in two equal halves along its longest axis; below, at the
//! position that minimises the total surface area of the two children
//! (over all three axes, points sorted, each child's area weighted by its
//! point count, at multiples of [`LEAF`] points so leaves are full);
//! leaves hold at most [`LEAF`] points. Each node carries the umbra bits of §3.3 A.

/// Points per leaf (the paper's 16).
pub const LEAF: usize = 16;
/// Above this many points the split is the spatial median (the paper's
/// 1K).
pub const SPATIAL_ABOVE: usize = 1024;

/// A node: its box, its children or its points, and its umbra bits.
#[derive(Debug, Clone)]
pub struct Node {
    /// Box corners.
    pub lo: [f64; 3],
    /// Box corners.
    pub hi: [f64; 3],
    /// Inner node: index of the left child (the right is `left + 1`);
    /// leaf: first point in [`Hierarchy::points`].
    pub first: u32,
    /// Leaf: its point count; inner node: 0.
    pub count: u32,
    /// Group-umbra bits (AND over the points below).
    pub group_umbra: u128,
    /// Full-umbra bit.
    pub full: bool,
    /// Every receiver below is sealed: no open caster's hole is on any
    /// segment from it to the light (see `Chunk::seal`), so open casters'
    /// back faces skip the node.
    pub sealed: bool,
}

/// The tree over some receivers.
#[derive(Debug, Clone, Default)]
pub struct Hierarchy {
    /// Nodes; the root is node 0.
    pub nodes: Vec<Node>,
    /// Receiver indices in leaf order.
    pub points: Vec<u32>,
}

impl Hierarchy {
    /// Builds the tree over receivers `ids` with positions `pos` (indexed
    /// by receiver).
    pub fn build(pos: &[[f64; 3]], ids: Vec<u32>) -> Hierarchy {
        Hierarchy::build_keyed(pos, ids, None)
    }

    /// [`Hierarchy::build`] with ties between equal coordinates broken by
    /// `key[id]` (else by the id): a relabelling of the receivers that
    /// carries their keys builds the same tree.
    pub fn build_keyed(pos: &[[f64; 3]], ids: Vec<u32>, key: Option<&[u32]>) -> Hierarchy {
        let mut h = Hierarchy {
            nodes: Vec::with_capacity(2 * ids.len() / LEAF + 1),
            points: ids,
        };
        if h.points.is_empty() {
            return h;
        }
        h.nodes.push(empty_node());
        let n = h.points.len();
        let mut scratch = Vec::new();
        let key = Key(key);
        h.build_node(pos, key, 0, 0, n, &mut scratch);
        h
    }

    /// Sets every node's `sealed` bit: the AND of `sealed[r]` over the
    /// receivers below it.
    pub fn mark_sealed(&mut self, sealed: &[bool]) {
        if !self.nodes.is_empty() {
            self.mark_sealed_below(0, sealed);
        }
    }

    fn mark_sealed_below(&mut self, node: usize, sealed: &[bool]) -> bool {
        let (first, count) = (
            self.nodes[node].first as usize,
            self.nodes[node].count as usize,
        );
        let all = if count > 0 {
            self.points[first..first + count]
                .iter()
                .all(|&r| sealed[r as usize])
        } else {
            // Both children are visited (no short circuit): each needs its bit.
            let left = self.mark_sealed_below(first, sealed);
            let right = self.mark_sealed_below(first + 1, sealed);
            left && right
        };
        self.nodes[node].sealed = all;
        all
    }

    /// Bytes held.
    pub fn bytes(&self) -> u64 {
        (self.nodes.capacity() * std::mem::size_of::<Node>() + self.points.capacity() * 4) as u64
    }

    fn build_node(
        &mut self,
        pos: &[[f64; 3]],
        key: Key,
        node: usize,
        s: usize,
        e: usize,
        scratch: &mut Vec<u32>,
    ) {
        let (lo, hi) = bounds(pos, &self.points[s..e]);
        self.nodes[node].lo = lo;
        self.nodes[node].hi = hi;
        let n = e - s;
        if n <= LEAF {
            self.nodes[node].first = s as u32;
            self.nodes[node].count = n as u32;
            return;
        }
        let mid = if n > SPATIAL_ABOVE {
            spatial_median(pos, key, &mut self.points[s..e], lo, hi)
        } else {
            surface_area_split(pos, key, &mut self.points[s..e], scratch)
        };
        let mid = s + mid;
        let left = self.nodes.len();
        self.nodes.push(empty_node());
        self.nodes.push(empty_node());
        self.nodes[node].first = left as u32;
        self.nodes[node].count = 0;
        self.build_node(pos, key, left, s, mid, scratch);
        self.build_node(pos, key, left + 1, mid, e, scratch);
    }
}

/// The tie-break key of the receivers.
#[derive(Clone, Copy)]
struct Key<'a>(Option<&'a [u32]>);

impl Key<'_> {
    #[inline(always)]
    fn of(self, id: u32) -> u32 {
        match self.0 {
            Some(k) => k[id as usize],
            None => id,
        }
    }
}

fn empty_node() -> Node {
    Node {
        lo: [0.0; 3],
        hi: [0.0; 3],
        first: 0,
        count: 0,
        group_umbra: 0,
        full: false,
        sealed: false,
    }
}

fn bounds(pos: &[[f64; 3]], ids: &[u32]) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for &i in ids {
        let p = pos[i as usize];
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    (lo, hi)
}

fn longest(lo: [f64; 3], hi: [f64; 3]) -> usize {
    let e = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    if e[0] >= e[1] && e[0] >= e[2] {
        0
    } else if e[1] >= e[2] {
        1
    } else {
        2
    }
}

/// Partitions at the middle of the box's longest axis; the count on the
/// left. Falls back to the median by count when one side would be empty
/// (coincident points).
fn spatial_median(
    pos: &[[f64; 3]],
    key: Key,
    ids: &mut [u32],
    lo: [f64; 3],
    hi: [f64; 3],
) -> usize {
    let a = longest(lo, hi);
    let m = 0.5 * (lo[a] + hi[a]);
    let mut i = 0;
    for j in 0..ids.len() {
        if pos[ids[j] as usize][a] < m {
            ids.swap(i, j);
            i += 1;
        }
    }
    if i == 0 || i == ids.len() {
        ids.sort_unstable_by(|&x, &y| {
            pos[x as usize][a]
                .total_cmp(&pos[y as usize][a])
                .then(key.of(x).cmp(&key.of(y)))
        });
        return ids.len() / 2;
    }
    i
}

fn area(lo: [f64; 3], hi: [f64; 3]) -> f64 {
    let e = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
}

/// The split (axis, position in sorted order) with the least total
/// surface area of the two children; `ids` left sorted along that axis.
fn surface_area_split(
    pos: &[[f64; 3]],
    key: Key,
    ids: &mut [u32],
    scratch: &mut Vec<u32>,
) -> usize {
    let n = ids.len();
    let mut best = (f64::INFINITY, 0usize, n / 2);
    let mut right_area = vec![0.0f64; n];
    for a in 0..3 {
        scratch.clear();
        scratch.extend_from_slice(ids);
        scratch.sort_unstable_by(|&x, &y| {
            pos[x as usize][a]
                .total_cmp(&pos[y as usize][a])
                .then(key.of(x).cmp(&key.of(y)))
        });
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for k in (1..n).rev() {
            grow(&mut lo, &mut hi, pos[scratch[k] as usize]);
            right_area[k] = area(lo, hi);
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for k in 1..n {
            grow(&mut lo, &mut hi, pos[scratch[k - 1] as usize]);
            // Splits into whole leaves only: a node of n points ends in
            // ⌈n / 16⌉ leaves, as the paper's leaves of 16 points.
            if k % LEAF != 0 {
                continue;
            }
            let cost = area(lo, hi) * k as f64 + right_area[k] * (n - k) as f64;
            if cost < best.0 {
                best = (cost, a, k);
            }
        }
    }
    let a = best.1;
    ids.sort_unstable_by(|&x, &y| {
        pos[x as usize][a]
            .total_cmp(&pos[y as usize][a])
            .then(key.of(x).cmp(&key.of(y)))
    });
    best.2
}

fn grow(lo: &mut [f64; 3], hi: &mut [f64; 3], p: [f64; 3]) {
    for a in 0..3 {
        lo[a] = lo[a].min(p[a]);
        hi[a] = hi[a].max(p[a]);
    }
}
