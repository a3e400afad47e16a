//! False box hits (SPEC 13.2): a walk of a built hierarchy that tests, from
//! the roots down, every node whose parent's box the ray meets before the
//! reference's closest hit, once with the stored box and once with the
//! exact tight box.

use glam::DVec3;
use serde::Serialize;

use super::Box64;
use crate::store::{node_box_grid, Hierarchy};

/// What the walks of some rays counted.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct WalkCounts {
    /// Rays walked.
    pub rays: u64,
    /// Box tests of the walk with stored boxes.
    pub tests: u64,
    /// Of those, tests the stored box passes.
    pub stored_hits: u64,
    /// Of those, tests the exact box of the same node fails: false box hits.
    pub false_hits: u64,
    /// Box tests of the same walk with the exact boxes instead.
    pub exact_tests: u64,
}

impl WalkCounts {
    /// Adds `o`'s counts.
    pub fn add(&mut self, o: &WalkCounts) {
        self.rays += o.rays;
        self.tests += o.tests;
        self.stored_hits += o.stored_hits;
        self.false_hits += o.false_hits;
        self.exact_tests += o.exact_tests;
    }
}

/// Stored boxes of `h` in grid units, index = node index.
pub fn stored_boxes(h: &Hierarchy) -> Vec<Box64> {
    h.nodes
        .iter()
        .map(|n| {
            let (lo, hi) = node_box_grid(n, &h.params);
            Box64 {
                lo: DVec3::from_array(lo),
                hi: DVec3::from_array(hi),
            }
        })
        .collect()
}

/// Walks one ray (grid units: `org`, `dir`, over `[0, t_end]`) through `h`
/// twice: with `stored` boxes and with `exact` ones (`None`: empty content).
pub fn walk_ray(
    h: &Hierarchy,
    stored: &[Box64],
    exact: &[Option<Box64>],
    org: DVec3,
    dir: DVec3,
    t_end: f64,
) -> WalkCounts {
    let mut c = WalkCounts {
        rays: 1,
        ..Default::default()
    };
    let exact_hit = |i: usize| exact[i].is_some_and(|b| b.hit(org, dir, 0.0, t_end));
    let mut stack: Vec<usize> = (0..h.root_count as usize).collect();
    while let Some(i) = stack.pop() {
        c.tests += 1;
        if !stored[i].hit(org, dir, 0.0, t_end) {
            continue;
        }
        c.stored_hits += 1;
        c.false_hits += !exact_hit(i) as u64;
        push_children(h, i, &mut stack);
    }
    let mut stack: Vec<usize> = (0..h.root_count as usize).collect();
    while let Some(i) = stack.pop() {
        c.exact_tests += 1;
        if exact_hit(i) {
            push_children(h, i, &mut stack);
        }
    }
    c
}

fn push_children(h: &Hierarchy, i: usize, stack: &mut Vec<usize>) {
    let n = &h.nodes[i];
    if !n.leaf {
        stack.extend(
            h.children_of(n)
                .iter()
                .filter(|r| r.hier == h.id)
                .map(|r| r.node as usize),
        );
    }
}
