//! A frame's merges, one per merge group (paragraph 67, SPEC 12.2): the
//! checker on every merged hierarchy redone this frame, the merging
//! module's RTL on it, and what the report says of each group.

use golden::frames::{FrameReport, Frames, GroupReport};
use golden::merge::MergeMode;
use golden::scene::Scene;
use serde::Serialize;

use super::merge_rtl::{MergeRtl, MergeRtlFrame};
use super::merger_rtl::{FrameMerge, MergerGroup, MergerRtl, MergerRtlFrame};
use super::pipeline::{bar, Options, RtlInfo, StageSeconds};

/// One merge group in one frame.
#[derive(Serialize, Clone)]
pub struct GroupOut {
    /// The group's objects present this frame, by name.
    pub objects: Vec<String>,
    /// The hierarchy traced for the group: its merged hierarchy's id, or
    /// the object's own when it is alone.
    pub root: Option<u8>,
    /// The merge was redone this frame.
    pub merged: bool,
    pub merge_level: Option<u8>,
    pub nodes_created: u64,
    /// Records of the group's merged hierarchy (0 when it has none).
    pub merged_nodes: u64,
    /// The merging module's stages on this frame's merge of the group.
    pub merge_rtl: Option<MergeRtlFrame>,
    /// The group's merge in the frame's run of the hierarchy merger top.
    pub merger_rtl: Option<MergerGroup>,
}

/// What the run keeps across frames for the merges.
pub struct MergeStage<'a> {
    pub scene: &'a Scene,
    pub options: &'a Options,
    pub rtl: MergeRtl,
    pub merger: MergerRtl,
}

/// One group in frame `k`: what the checks and the RTL are about.
struct At<'a> {
    k: usize,
    frames: &'a Frames,
    g: &'a GroupReport,
    /// ` of group n (names)` when the scene has several groups, else empty.
    label: &'a str,
}

/// Frame `k`: its report and each group's label (as [`At`]'s).
struct FrameAt<'a> {
    k: usize,
    frames: &'a Frames,
    rep: &'a FrameReport,
    labels: &'a [String],
}

/// The lines a frame prints: what was simulated and what was skipped.
pub struct Lines<'a> {
    pub simulated: &'a mut Vec<String>,
    pub skipped: &'a mut Vec<String>,
}

impl MergeStage<'_> {
    /// Every group of frame `k`'s report `rep`: checked when its merge was
    /// redone, then through the merging module's RTL; then the frame's
    /// merges back to back through the hierarchy merger top (its run).
    pub fn run(
        &mut self,
        k: usize,
        frames: &Frames,
        rep: &FrameReport,
        lines: &mut Lines,
        secs: &mut StageSeconds,
        rtl_info: &mut RtlInfo,
    ) -> Result<(Vec<GroupOut>, Option<MergerRtlFrame>), String> {
        let many = rep.groups.len() > 1;
        let mut out = Vec::with_capacity(rep.groups.len());
        let mut labels = Vec::with_capacity(rep.groups.len());
        for (n, g) in rep.groups.iter().enumerate() {
            let names: Vec<String> = g
                .inputs
                .iter()
                .map(|&id| self.scene.objects[id as usize].name.clone())
                .collect();
            let label = if many {
                format!(" of group {n} ({})", names.join(", "))
            } else {
                String::new()
            };
            let at = At {
                k,
                frames,
                g,
                label: &label,
            };
            let nodes_created = self.check(&at, lines, secs)?;
            let merged_nodes = match (g.is_merged(), g.root) {
                (true, Some(root)) => frames
                    .world
                    .store
                    .get(root)
                    .map_or(0, |h| h.nodes.len() as u64),
                _ => 0,
            };
            let merge_rtl = self.rtl(&at, lines, secs, rtl_info)?;
            out.push(GroupOut {
                objects: names,
                root: g.root,
                merged: g.merged,
                merge_level: g.merge_level,
                nodes_created,
                merged_nodes,
                merge_rtl,
                merger_rtl: None,
            });
            labels.push(label);
        }
        let at = FrameAt {
            k,
            frames,
            rep,
            labels: &labels,
        };
        let run = self.merger(&at, &mut out, lines, secs, rtl_info)?;
        Ok((out, run))
    }

    /// The merge's lines and, when it was redone, the checker on it; the
    /// nodes it created.
    fn check(&self, at: &At, lines: &mut Lines, secs: &mut StageSeconds) -> Result<u64, String> {
        let At {
            k,
            frames,
            g,
            label,
        } = *at;
        let fx = &self.scene.effects;
        let (Some(s), Some(root)) = (g.merge_stats.as_ref().filter(|_| g.merged), g.root) else {
            lines.skipped.push(if g.is_merged() {
                format!("merge{label}: no input changed, last frame's merged hierarchy reused")
            } else {
                format!("merge{label}: a single object, nothing to merge")
            });
            return Ok(0);
        };
        lines.simulated.push(format!(
            "merge{label} ({:?}): level {:?}, {} nodes created, {} input nodes reused",
            fx.merge,
            g.merge_level,
            s.created(),
            s.reused()
        ));
        let t = std::time::Instant::now();
        frames
            .world
            .check(root)
            .map_err(|e| format!("frame {k}: merged hierarchy{label}: {e}"))?;
        secs.check += t.elapsed().as_secs_f64();
        lines
            .simulated
            .push(format!("checker on the merged hierarchy{label}: passed"));
        Ok(s.created())
    }

    /// Whether `unit` runs on the group's merge this frame: it was redone
    /// and the run simulates RTL; else the reason is said (nothing for a
    /// group with no merge).
    fn simulates(&self, g: &GroupReport, unit: &str, label: &str, lines: &mut Lines) -> bool {
        if !g.merged {
            if g.is_merged() {
                lines
                    .skipped
                    .push(format!("{unit}{label}: no merge redone this frame"));
            }
            return false;
        }
        if !self.options.rtl {
            lines.skipped.push(format!("{unit}{label}: --no-rtl"));
            return false;
        }
        true
    }

    /// The merging module's RTL on the group's merge, when it was redone
    /// and the run simulates RTL.
    fn rtl(
        &mut self,
        at: &At,
        lines: &mut Lines,
        secs: &mut StageSeconds,
        rtl_info: &mut RtlInfo,
    ) -> Result<Option<MergeRtlFrame>, String> {
        let At {
            k,
            frames,
            g,
            label,
        } = *at;
        let fx = &self.scene.effects;
        if !self.simulates(g, "merging module RTL", label, lines) {
            return Ok(None);
        }
        let t = std::time::Instant::now();
        let b = bar(self.options, format!("frame {k} merge RTL"));
        b.set_length(1);
        let r = match (g.merge_level, fx.merge) {
            (Some(level), _) => {
                let r = self.rtl.run_frame(
                    &frames.world,
                    &g.inputs,
                    level,
                    fx.merge,
                    fx.upper_build,
                )?;
                lines.simulated.push(format!(
                    "merging module RTL{label} at level {level}: {} ({} beats in, {} cycles, {} mismatches)",
                    r.stages.join(", "),
                    r.beats_in,
                    r.cycles,
                    r.mismatches
                ));
                if !fx.upper_build {
                    lines.skipped.push(
                        "S616 upper-level RTL: the scene does not ask for the upper-level build"
                            .into(),
                    );
                }
                if !matches!(fx.merge, MergeMode::Overlap { .. }) {
                    lines.skipped.push("S608 overlap counter RTL: the merge mode does not count overlap (the merging module is built without it)".into());
                }
                r
            }
            (None, MergeMode::PerNode { num, den }) => {
                let stats = g
                    .merge_stats
                    .as_ref()
                    .ok_or("per-node merge RTL: the frame's merge has no statistics")?;
                let r = self
                    .rtl
                    .run_per_node_frame(&frames.world, &g.inputs, (num, den), stats)?;
                lines.simulated.push(format!(
                    "merging module RTL{label}, per-node:{num}/{den}: {} ({} beats in, {} cycles, {} mismatches; base per LOD = golden per-node merge)",
                    r.stages.join(", "),
                    r.beats_in,
                    r.cycles,
                    r.mismatches
                ));
                lines.skipped.push(if fx.upper_build {
                    "S616 upper-level RTL: per-node merges have base nodes at several LODs (S616 is built for one level)".into()
                } else {
                    "S616 upper-level RTL: the scene does not ask for the upper-level build".into()
                });
                lines.skipped.push("S608 overlap counter RTL: the per-node module decides per voxel (no overlap counter)".into());
                r
            }
            (None, mode) => {
                b.finish_and_clear();
                lines.skipped.push(format!(
                    "merging module RTL{label}: mode {mode} has no merging level"
                ));
                return Ok(None);
            }
        };
        b.finish_and_clear();
        if r.build_seconds > 0.0 {
            rtl_info.merge = format!(
                "built ({}): {}",
                self.rtl.engine.label(),
                r.stages.join(", ")
            );
        }
        secs.rtl += t.elapsed().as_secs_f64();
        Ok(Some(r))
    }

    /// The hierarchy merger top on the frame's merges redone, back to
    /// back on one top, when the run simulates RTL (SPEC 12.2 step 4):
    /// each group's part in `out`, the run returned.
    fn merger(
        &mut self,
        at: &FrameAt,
        out: &mut [GroupOut],
        lines: &mut Lines,
        secs: &mut StageSeconds,
        rtl_info: &mut RtlInfo,
    ) -> Result<Option<MergerRtlFrame>, String> {
        let FrameAt {
            k,
            frames,
            rep,
            labels,
        } = *at;
        let mut merges = Vec::new();
        let mut which = Vec::new();
        for (n, g) in rep.groups.iter().enumerate() {
            let unit = "hierarchy merger RTL";
            if let Some(root) = g
                .root
                .filter(|_| self.simulates(g, unit, &labels[n], lines))
            {
                merges.push(FrameMerge {
                    ids: g.inputs.clone(),
                    out: root,
                });
                which.push(n);
            }
        }
        if merges.is_empty() {
            return Ok(None);
        }
        let t = std::time::Instant::now();
        let b = bar(self.options, format!("frame {k} merger RTL"));
        b.set_length(1);
        let mode = self.scene.effects.merge;
        let r = self.merger.run_frame(&frames.world, &merges, mode);
        b.finish_and_clear();
        secs.rtl += t.elapsed().as_secs_f64();
        let r = r?;
        let engine = self.merger.engine_label();
        for (&n, m) in which.iter().zip(r.merges) {
            let label = &labels[n];
            match m {
                Ok(m) => {
                    lines.simulated.push(format!(
                        "hierarchy merger RTL{label}: merge {} of the frame's run, {} inputs, \
                         {} records, {} references, {} store reads by golden's units",
                        m.order, m.n, m.golden_records, m.golden_refs, m.golden_store_reads
                    ));
                    out[n].merger_rtl = Some(m);
                }
                Err(why) => lines
                    .skipped
                    .push(format!("hierarchy merger RTL{label}: {why}")),
            }
        }
        let Some(r) = r.run else {
            return Ok(None);
        };
        if r.build_seconds > 0.0 {
            lines.simulated.push(format!(
                "hierarchy unit RTL: {} generated and built ({engine}, {:.1} s)",
                r.top, r.build_seconds
            ));
            rtl_info.merger = format!("built ({engine}): {}", r.top);
        }
        lines.simulated.push(format!(
            "hierarchy unit RTL ({engine}): {} determine commands, then {} on one merger top; {} cycles: {} until the first \
             merge was taken, {} merging; {} records ({:.2} cycles/node, {:.2} store reads/node, {:.3} records/cycle){}, {} \
             mismatches{}",
            r.determines,
            match r.merges {
                1 => "the frame's merge".to_string(),
                n => format!("the frame's {n} merges back to back"),
            },
            r.cycles,
            r.determine_cycles,
            r.merge_cycles,
            r.records,
            r.cycles_per_node,
            r.store_reads_per_node,
            r.records_per_cycle,
            port_said(&r),
            r.mismatches,
            r.first_mismatch
                .as_ref()
                .map_or(String::new(), |m| format!(" (first: {m})"))
        ));
        Ok(Some(r))
    }
}

/// What a shared store port allowed a run: its reads (and golden's
/// units'), and its records per cycle against the port's one read a clock.
fn port_said(r: &MergerRtlFrame) -> String {
    let (Some(latency), Some(allowed), Some(share)) =
        (r.store_latency, r.records_allowed_per_cycle, r.of_port)
    else {
        return String::new();
    };
    format!(
        "; store port {} (latency {latency}): {} reads ({} by golden's units), {:.4} \
         records/cycle of the {:.4} the port allows: {:.3} of the port",
        r.store_port, r.store_reads, r.golden_store_reads, r.records_per_cycle, allowed, share
    )
}
