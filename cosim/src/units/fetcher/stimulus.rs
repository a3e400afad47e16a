//! The fetcher's stimulus, all from golden: builder-made soups
//! (`golden::merge::stimulus::try_soup`), translated at random (mostly
//! inside the scene), walked to random levels with random flags, and the
//! same inputs corrupted so that every error code occurs; per-node
//! fetches are the inputs of random per-node merges with the module's
//! decisions varied.

use golden::merge::fetcher::{
    fetch_transaction, fetch_transaction_with_reports, FetchCmd, FetchOut, FetchSizes,
    FetchTransaction,
};
use golden::merge::per_node::unit::{random_per_node_case, PerNodeReport};
use golden::params::Params;
use golden::store::Hierarchy;
use golden::translate::stimulus::SplitMix64;
use golden::translate::table::pack_entry;
use golden::translate::Translation;

use crate::error::{CosimError, Result};

fn golden_err(what: impl std::fmt::Display) -> CosimError {
    CosimError::Design {
        what: format!("golden fetcher: {what}"),
    }
}

/// A soup hierarchy `id` of `n` triangles in the scene's `2^-3` corner, if
/// it builds and its arrays fit the configuration's `I`.
pub fn soup(p: &Params, id: u8, n: usize, size: f32, seed: u64) -> Option<Hierarchy> {
    let h = golden::merge::stimulus::try_soup(p, id, n, size, seed).ok()?;
    let cap = p.index_capacity() as usize;
    (h.nodes.len() < cap && h.refs.len() < cap).then_some(h)
}

/// A random translation of `h`: mostly at or above its top, inside the
/// scene; sometimes past the edge or below the top (errors).
pub fn random_translation(rng: &mut SplitMix64, h: &Hierarchy) -> Translation {
    let top = h.top_lod;
    let p = &h.params;
    let lod = if rng.below(20) == 0 && top < p.max_lod {
        top + 1
    } else {
        rng.below(top as u64 + 1) as u8
    };
    let t = [0, 1, 2].map(|a| {
        let shift = top - lod;
        let (mut lo, mut hi) = (i64::MAX, i64::MIN);
        for n in h.roots() {
            let c = [n.voxel.x, n.voxel.y, n.voxel.z][a] as i64 >> shift;
            lo = lo.min(c);
            hi = hi.max(c);
        }
        let room_hi = (1i64 << lod) - 1 - hi;
        if rng.below(25) == 0 {
            room_hi + 1
        } else if room_hi + lo <= 0 {
            0
        } else {
            rng.range_i64(-lo, room_hi)
        }
    });
    Translation { lod, t }
}

/// `h` with one random defect (or none), and the sizes' limits in play.
pub fn corrupt(rng: &mut SplitMix64, h: &Hierarchy) -> Hierarchy {
    let mut h = h.clone();
    let p = h.params;
    let n = h.nodes.len();
    let pick = rng.below(n as u64) as usize;
    match rng.below(16) {
        0 => h.nodes[pick].voxel.lod = (h.nodes[pick].voxel.lod + 1).min(p.max_lod),
        1 => {
            let lod = h.nodes[pick].voxel.lod;
            if lod < p.max_lod {
                h.nodes[pick].voxel.x = 1 << lod;
            }
        }
        2 if p.quant_bits > 0 => {
            h.nodes[pick].lo[1] = 1;
            h.nodes[pick].hi[1] = 0;
        }
        3 => h.nodes[pick].count = 0,
        4 if !h.nodes[pick].leaf => h.nodes[pick].count = h.refs.len() as u32,
        5 if !h.refs.is_empty() => {
            let j = rng.below(h.refs.len() as u64) as usize;
            h.refs[j].hier = ((h.id as u64 + 1) % p.hier_capacity()) as u8;
        }
        6 if !h.refs.is_empty() => {
            let j = rng.below(h.refs.len() as u64) as usize;
            h.refs[j].node = n as u32 + rng.below(3) as u32;
        }
        7 if h.refs.len() >= 2 => {
            let j = rng.below(h.refs.len() as u64 - 1) as usize;
            h.refs.swap(j, j + 1);
        }
        8 => h.root_count = if rng.below(2) == 0 { 0 } else { n as u32 + 1 },
        // Every node a root: LOD errors, or more roots than the sorter holds.
        9 => h.root_count = n as u32,
        _ => {}
    }
    h
}

/// Soups kept at once: inputs are drawn from this pool, so that one soup
/// meets several translations, defects and commands.
const POOL: usize = 24;

/// Random fetches from `seed` until `cmds` commands: soups of 1 to `most`
/// triangles, random translations, corrupted half the time, each with 1 to
/// 4 commands at random levels.
pub fn random_fetches(
    p: &Params,
    sizes: FetchSizes,
    seed: u64,
    cmds: usize,
    most: usize,
) -> Result<Vec<FetchTransaction>> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut pool: Vec<Hierarchy> = Vec::new();
    let mut sent = 0;
    while sent < cmds {
        if pool.len() < POOL || rng.below(8) == 0 {
            let n = 1 + rng.below(most as u64) as usize;
            let size = [0.01, 0.05, 0.2][rng.below(3) as usize];
            let id = rng.below(p.hier_capacity()) as u8;
            if let Some(h) = soup(p, id, n, size, rng.next_u64()) {
                if pool.len() >= POOL {
                    let at = rng.below(pool.len() as u64) as usize;
                    pool[at] = h;
                } else {
                    pool.push(h);
                }
            }
            continue;
        }
        let h = &pool[rng.below(pool.len() as u64) as usize];
        let t = random_translation(&mut rng, h);
        let h = if rng.below(2) == 0 {
            corrupt(&mut rng, h)
        } else {
            h.clone()
        };
        let entry = if rng.below(40) == 0 {
            0
        } else {
            pack_entry(Some(&t), p)
        };
        let list = random_commands(&mut rng, p, &h);
        sent += list.len();
        out.push(fetch_transaction(&h, entry, &list, sizes).map_err(golden_err)?);
    }
    Ok(out)
}

/// 1 to 4 level commands on `h`, the last one ending the input.
fn random_commands(rng: &mut SplitMix64, p: &Params, h: &Hierarchy) -> Vec<FetchCmd> {
    let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap_or(0);
    let k = 1 + rng.below(4) as usize;
    (0..k)
        .map(|i| {
            let lod = (h.top_lod as u64 + rng.below((deepest - h.top_lod) as u64 + 3))
                .saturating_sub(1)
                .min(p.max_lod as u64) as u8;
            // A third of the commands send several levels from one walk
            // (from above the top at times), a few have `from` past `lod`.
            let from = match rng.below(12) {
                0..=3 => rng.below(lod as u64 + 1) as u8,
                4 => (lod as u64 + 1 + rng.below(3)).min((1 << p.lod_bits()) - 1) as u8,
                _ => lod,
            };
            FetchCmd {
                from,
                ..FetchCmd::level(lod, rng.below(2) == 0, rng.below(3) != 0, i + 1 == k)
            }
        })
        .collect()
}

/// What the per-node stimulus reached.
#[derive(Clone, Default, Debug)]
pub struct PerNodeSeen {
    /// Per-node merges whose inputs were fetched.
    pub fetches: usize,
    /// Passes (`PassEnd` and other non-decision reports) over all inputs.
    pub passes: usize,
    /// Inputs fetched in more than one pass.
    pub multi_pass: usize,
    /// Decisions to descend.
    pub descents: usize,
    /// Probe reads.
    pub probes: usize,
    /// Inputs first given a level command.
    pub level_cmds: usize,
    /// Inputs whose `out` has an error.
    pub errors: usize,
    /// Inputs corrupted.
    pub corrupted: usize,
}

impl PerNodeSeen {
    /// Adds the counts of `other` (another chunk of one run).
    pub fn add(&mut self, other: &PerNodeSeen) {
        self.fetches += other.fetches;
        self.passes += other.passes;
        self.multi_pass += other.multi_pass;
        self.descents += other.descents;
        self.probes += other.probes;
        self.level_cmds += other.level_cmds;
        self.errors += other.errors;
        self.corrupted += other.corrupted;
    }
}

/// Random per-node fetches from `seed` until `merges` merges: the inputs
/// of random per-node merges (`random_per_node_case`, 2-4 inputs by seed,
/// trees 4 LODs deep, ratio 1/2 or 0/1), each input's fetcher given the
/// module's `report` stream with one descent in 4 refused (so descents are
/// random, at the contested voxels), one input in 4 corrupted (errors:
/// then only the passes' `End`s follow it), half the inputs first given a
/// level command.
pub fn random_per_node_fetches(
    p: &Params,
    sizes: FetchSizes,
    seed: u64,
    merges: usize,
) -> Result<(Vec<FetchTransaction>, PerNodeSeen)> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    let mut seen = PerNodeSeen::default();
    let k = 2 + (seed % 3) as usize;
    while seen.fetches < merges {
        let c = random_per_node_case(&mut rng, p, k, 4);
        let (num, den) = if rng.below(2) == 0 { (1, 2) } else { (0, 1) };
        let Ok(tx) = c.transaction(p, num, den) else {
            continue;
        };
        if tx.passes == 0 {
            continue;
        }
        seen.fetches += 1;
        for (h, t) in c.hierarchies.iter().zip(&c.translations) {
            let reports = refuse_some_descents(&mut rng, &tx.reports);
            let h = if rng.below(4) == 0 {
                seen.corrupted += 1;
                corrupt(&mut rng, h)
            } else {
                h.clone()
            };
            let entry = if rng.below(40) == 0 {
                0
            } else {
                pack_entry(Some(t), p)
            };
            let mut cmds = Vec::new();
            if rng.below(2) == 0 {
                seen.level_cmds += 1;
                let lod = c.lo.saturating_sub(rng.below(2) as u8);
                let cmd = FetchCmd::level(lod, rng.below(2) == 0, rng.below(2) == 0, false);
                cmds.push(cmd);
            }
            cmds.push(FetchCmd::per_node(c.lo, rng.below(4) != 0, true));
            let f = fetch_transaction_with_reports(&h, entry, &cmds, &reports, sizes)
                .map_err(golden_err)?;
            count_per_node(&mut seen, &f);
            out.push(f);
        }
    }
    Ok((out, seen))
}

/// The module's `reports` with one descent in 4 refused; a pass left with
/// none ends the merge (the module's `more`: some voxel descended, `l < D`).
fn refuse_some_descents(rng: &mut SplitMix64, reports: &[PerNodeReport]) -> Vec<PerNodeReport> {
    let mut out = Vec::new();
    let mut descended = false;
    for &r in reports {
        let mut r = r;
        match &mut r {
            PerNodeReport::Decision { descend, .. } => {
                *descend = *descend && rng.below(4) != 0;
                descended |= *descend;
            }
            PerNodeReport::PassEnd { more, .. } => {
                *more = *more && descended;
                descended = false;
            }
            _ => {}
        }
        out.push(r);
        if matches!(r, PerNodeReport::PassEnd { more: false, .. }) {
            break;
        }
    }
    out
}

/// Adds what one per-node fetch `f` reaches to `seen`.
fn count_per_node(seen: &mut PerNodeSeen, f: &FetchTransaction) {
    let passes = f
        .reports
        .iter()
        .filter(|r| !matches!(r, PerNodeReport::Decision { .. }))
        .count();
    seen.passes += passes;
    seen.multi_pass += (passes > 1) as usize;
    seen.descents += f
        .reports
        .iter()
        .filter(|r| matches!(r, PerNodeReport::Decision { descend: true, .. }))
        .count();
    seen.probes += f.probe_reqs.len();
    seen.errors += f.out.iter().any(|o| matches!(o, FetchOut::Error { .. })) as usize;
}

/// The module's `report` stream of a per-node merge of `h` alone at `t`
/// from its top down: every inner voxel of every pass descends, so every
/// node below the top is read once as a live node and once as a probe (the
/// per-node steady state).
pub fn descend_everywhere(h: &Hierarchy, t: &Translation) -> Result<Vec<PerNodeReport>> {
    let deepest = h
        .nodes
        .iter()
        .map(|n| n.voxel.lod)
        .max()
        .unwrap_or(h.top_lod);
    let mut reports = Vec::new();
    for l in h.top_lod..=deepest {
        let w = golden::merge::fetcher::walk::walk_input(h, 0, t, l).map_err(golden_err)?;
        let (_, mut at) = golden::merge::fetcher::walk::collect(std::slice::from_ref(&w), l);
        golden::merge::merge_level::sort_stream(&mut at);
        for n in at.iter().filter(|n| !n.record.leaf) {
            reports.push(PerNodeReport::Decision {
                voxel: n.record.voxel,
                shared: 1,
                union: 1,
                descend: true,
            });
        }
        reports.push(PerNodeReport::PassEnd {
            lod: l,
            more: l < deepest,
        });
    }
    Ok(reports)
}
