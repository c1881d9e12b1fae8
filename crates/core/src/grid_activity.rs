//! Which parts of the grid are in use: the grid's nodes, in their x-major order, are cut into
//! blocks of [`BLOCK_NODES`] consecutive nodes; a block is active in a step when P2G writes
//! one of its nodes (it marks the blocks of every particle's stencil). Only active blocks are
//! updated, cleared and kept in memory, so the work and memory of the grid follow the
//! particles, not the domain.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Nodes per block: 512, so a block of masses is one 4 KiB page and a block of 3D vectors
/// three.
pub const BLOCK_NODES: usize = 512;

/// The most blocks one particle's stencil marks: a range of at most two blocks per row of
/// the widest kernel (`mark_stencil` in `solver/particle_to_grid.rs`).
pub const MAX_BLOCKS_PER_PARTICLE: usize = 2 * crate::kernels::MAX_SPAN * crate::kernels::MAX_SPAN;

/// The active blocks of a sparse grid, and the marks of the transfer under way.
pub struct GridActivity {
    /// Bit per block: marked by a stencil since the last [`GridActivity::begin_step`].
    marks: Vec<AtomicU64>,
    /// Whether anything was marked since then.
    pending: AtomicBool,
    /// Bit per block: active this step.
    active_bits: Vec<u64>,
    /// Active blocks of this step, in the order their work is done (ascending).
    active: Vec<u32>,
    /// Nodes of the grid.
    nodes: usize,
    /// The most blocks active at once since the grid was built.
    peak: usize,
}

impl GridActivity {
    /// Tracking for a grid of `nodes` nodes, nothing active.
    pub fn new(nodes: usize) -> Self {
        let words = nodes.div_ceil(BLOCK_NODES).div_ceil(64);
        Self {
            marks: (0..words).map(|_| AtomicU64::new(0)).collect(),
            pending: AtomicBool::new(false),
            active_bits: vec![0; words],
            active: Vec::new(),
            nodes,
            peak: 0,
        }
    }

    /// Marks the blocks holding nodes `range` for the next step (thread-safe).
    #[inline(always)]
    pub fn mark(&self, range: Range<usize>) {
        let end = range.end.min(self.nodes);
        if range.start >= end {
            return;
        }
        let (first, last) = (range.start / BLOCK_NODES, (end - 1) / BLOCK_NODES);
        for block in first..=last {
            let (word, bit) = (&self.marks[block / 64], 1u64 << (block % 64));
            // Most marks repeat a neighbour's: read before the atomic write.
            if word.load(Ordering::Relaxed) & bit == 0 {
                word.fetch_or(bit, Ordering::Relaxed);
                self.pending.store(true, Ordering::Relaxed);
            }
        }
    }

    /// Whether blocks were marked since the last [`Self::begin_step`].
    pub fn has_marks(&self) -> bool {
        self.pending.load(Ordering::Relaxed)
    }

    /// The marked blocks become the active ones and the marks are reset. With `replace`, the
    /// blocks active before and not marked now drop out: calls `f(range, true)` for the node
    /// range of every block active before and now and `f(range, false)` for every block
    /// active before but not now (to be released), in ascending order. Without, the marked
    /// blocks join those active (a second transfer in a step whose grid was not cleared
    /// since: MUSL's) and `f` is not called.
    pub fn begin_step(&mut self, replace: bool, mut f: impl FnMut(Range<usize>, bool)) {
        self.pending.store(false, Ordering::Relaxed);
        let mut next = std::mem::take(&mut self.active);
        next.clear();
        for w in 0..self.marks.len() {
            let marked = self.marks[w].swap(0, Ordering::Relaxed);
            let before = self.active_bits[w];
            let now = if replace { marked } else { marked | before };
            self.active_bits[w] = now;
            let mut touched = if replace { before } else { 0 };
            while touched != 0 {
                let bit = touched.trailing_zeros() as usize;
                f(self.block_range(w * 64 + bit), now & (1 << bit) != 0);
                touched &= touched - 1;
            }
            let mut set = now;
            while set != 0 {
                next.push((w * 64 + set.trailing_zeros() as usize) as u32);
                set &= set - 1;
            }
        }
        self.active = next;
        self.peak = self.peak.max(self.active.len());
    }

    /// Makes the block of `node` active in this step (a wall's fold writing in front of
    /// nodes no stencil reached; an inactive block holds zeros).
    pub fn activate(&mut self, node: usize) {
        let block = node / BLOCK_NODES;
        let (word, bit) = (block / 64, 1u64 << (block % 64));
        if self.active_bits[word] & bit != 0 {
            return;
        }
        self.active_bits[word] |= bit;
        let at = self.active.partition_point(|&b| (b as usize) < block);
        self.active.insert(at, block as u32);
        self.peak = self.peak.max(self.active.len());
    }

    /// Whether `node` lies in an active block this step.
    #[inline(always)]
    pub fn is_active(&self, node: usize) -> bool {
        let block = node / BLOCK_NODES;
        self.active_bits[block / 64] & (1u64 << (block % 64)) != 0
    }

    /// Active blocks this step.
    pub fn active_blocks(&self) -> usize {
        self.active.len()
    }

    /// Node range of the `k`-th active block.
    #[inline(always)]
    pub fn active_range(&self, k: usize) -> Range<usize> {
        self.block_range(self.active[k] as usize)
    }

    /// The most blocks active at once so far.
    pub fn peak_blocks(&self) -> usize {
        self.peak
    }

    /// Bytes of the tracking itself.
    pub fn bytes(&self) -> usize {
        self.marks.len() * 8 + self.active_bits.len() * 8 + self.active.capacity() * 4
    }

    fn block_range(&self, block: usize) -> Range<usize> {
        let start = block * BLOCK_NODES;
        start..(start + BLOCK_NODES).min(self.nodes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn marks_become_the_active_blocks_and_old_ones_are_dropped() {
        let mut a = GridActivity::new(10 * BLOCK_NODES + 7);
        a.mark(10..20);
        a.mark(BLOCK_NODES - 1..BLOCK_NODES + 1);
        a.mark(10 * BLOCK_NODES..10 * BLOCK_NODES + 3);
        let mut seen = Vec::new();
        a.begin_step(true, |r, keep| seen.push((r, keep)));
        assert!(seen.is_empty());
        assert_eq!(a.active_blocks(), 3);
        assert_eq!(a.active_range(2), 10 * BLOCK_NODES..10 * BLOCK_NODES + 7);
        assert!(a.is_active(3) && a.is_active(BLOCK_NODES + 3) && !a.is_active(2 * BLOCK_NODES));
        // Next step only block 1 and block 5.
        a.mark(BLOCK_NODES + 4..BLOCK_NODES + 5);
        a.mark(5 * BLOCK_NODES..5 * BLOCK_NODES + 1);
        a.begin_step(true, |r, keep| seen.push((r, keep)));
        assert_eq!(
            seen,
            vec![
                (0..BLOCK_NODES, false),
                (BLOCK_NODES..2 * BLOCK_NODES, true),
                (10 * BLOCK_NODES..10 * BLOCK_NODES + 7, false)
            ]
        );
        a.activate(3 * BLOCK_NODES + 1);
        a.activate(3 * BLOCK_NODES + 2);
        let starts = |a: &GridActivity| -> Vec<usize> {
            (0..a.active_blocks())
                .map(|k| a.active_range(k).start)
                .collect()
        };
        assert_eq!(
            starts(&a),
            vec![BLOCK_NODES, 3 * BLOCK_NODES, 5 * BLOCK_NODES]
        );
        assert_eq!(a.peak_blocks(), 3);
        // A second transfer without a clear (MUSL's) adds its blocks and drops none.
        a.mark(7 * BLOCK_NODES..7 * BLOCK_NODES + 1);
        seen.clear();
        a.begin_step(false, |r, keep| seen.push((r, keep)));
        assert!(seen.is_empty());
        assert_eq!(
            starts(&a),
            vec![
                BLOCK_NODES,
                3 * BLOCK_NODES,
                5 * BLOCK_NODES,
                7 * BLOCK_NODES
            ]
        );
        assert_eq!(a.peak_blocks(), 4);
    }
}
