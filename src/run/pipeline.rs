//! The frame loop of `hiermerge run`: what is simulated, what is reused,
//! and the report.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;
use golden::frames::{FrameObject, FrameReport, Frames, Motion, ObjectAction};
use golden::mesh::Mesh;
use golden::saved::Provenance;
use golden::scene::Scene;
use golden::translate::Axis;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

use super::compare::{compare, Comparison, SUBSAMPLE};
use super::engine::RunEngine;
use super::merge_rtl::MergeRtl;
use super::merger_rtl::{MergerRtl, MergerRtlFrame, MergerStore};
use super::merges::{GroupOut, Lines, MergeStage};
use super::render::{trace_frame, RayCounts, Traced};
use super::rtl::{Placed, RtlFrame, TranslateRtl};
use crate::image::{heat_rgb, write_png};

/// How to run.
pub struct Options {
    /// The output folder the report names.
    pub out: PathBuf,
    /// Where the files are written meanwhile (the fresh folder that
    /// replaces `out` when the run is complete).
    pub write_to: PathBuf,
    /// Build and simulate RTL for the units the scene uses.
    pub rtl: bool,
    /// The simulator of every unit (`--engine`; Verilator by default).
    pub engine: RunEngine,
    /// Draw progress bars on stderr.
    pub progress: bool,
    /// Print per-frame lines on stderr.
    pub narrate: bool,
    /// Judge the compared rays' merged hits by the binary64 oracle (SPEC 6.10).
    pub verify: bool,
    /// Write the images and heat maps the report names; false for a caller
    /// that wants the report alone (each image is synced to disk: most of
    /// the time of a small scene's run).
    pub images: bool,
    /// How the hierarchy merger top reaches the store (`--store-port`,
    /// `--store-latency`; one shared read port by default).
    pub merger_store: MergerStore,
}

impl Options {
    /// The golden model alone, quietly, into `dir`: no RTL, no progress
    /// bars or frame lines, no oracle, no images (what a test of the
    /// model's frames wants; set the fields it needs besides).
    pub fn golden_only(dir: &Path) -> Options {
        Options {
            out: dir.to_path_buf(),
            write_to: dir.to_path_buf(),
            rtl: false,
            engine: RunEngine::Verilator,
            progress: false,
            narrate: false,
            verify: false,
            images: false,
            merger_store: MergerStore::default(),
        }
    }
}

/// The whole run.
#[derive(Serialize)]
pub struct RunReport {
    pub scene: String,
    pub params: golden::Params,
    pub frame_count: u32,
    pub objects: Vec<ObjectInfo>,
    pub effects: EffectsInfo,
    /// What happened to each unit's RTL over the run.
    pub rtl: RtlInfo,
    pub frames: Vec<FrameOut>,
    /// The last frame's image (what `image.png` and `heat.png` hold).
    pub image: ImageSummary,
    /// RTL mismatches plus merged-vs-separate hit mismatches, all frames.
    pub mismatches: u64,
    pub seconds: f64,
}

#[derive(Serialize)]
pub struct ObjectInfo {
    pub id: u8,
    pub name: String,
    pub motion: Motion,
    pub triangles: u64,
}

#[derive(Serialize)]
pub struct EffectsInfo {
    pub translation: bool,
    pub merge_mode: String,
    pub upper_build: bool,
    pub primary: bool,
    pub shadow: bool,
    pub reflection_depth: u32,
    pub clip_distance: f32,
}

#[derive(Serialize)]
pub struct RtlInfo {
    /// `built`, `not used by the scene`, `disabled (--no-rtl)`, `not needed`.
    pub translation: String,
    pub translation_build_seconds: f64,
    pub merge: String,
    /// The hierarchy merger top: `built (Verilator): <top>`, `not used by
    /// the scene`, `disabled (--no-rtl)`, `not needed`.
    pub merger: String,
    /// How the merger top reaches the store: `store port shared:3, latency
    /// 1` or `per-unit store ports`.
    pub merger_store: String,
    /// The engine the units ran on.
    pub engine: RunEngine,
}

#[derive(Serialize)]
pub struct ImageSummary {
    pub width: u32,
    pub height: u32,
    pub rays: u64,
    pub hits: u64,
    pub image: String,
    pub heat_map: String,
}

/// One frame.
#[derive(Serialize, Clone)]
pub struct FrameOut {
    pub frame: u32,
    pub actions: BTreeMap<String, ObjectAction>,
    pub built: usize,
    pub rebuilt: usize,
    /// Moved by a fraction of a voxel: the residual changed, the local geometry was rebuilt.
    pub moved: usize,
    pub retranslated: usize,
    pub reused: usize,
    /// Some group's merge was redone this frame.
    pub merged: bool,
    /// Over the groups.
    pub nodes_created: u64,
    /// Over the groups.
    pub merged_nodes: u64,
    /// Per merge group (paragraph 67; one unless the scene names groups).
    pub groups: Vec<GroupOut>,
    /// Largest placement residual this frame (world units) that the voxel
    /// grid could not express, over placed objects; their local geometry
    /// carries it (SPEC 7.10), so objects sit where the scene puts them.
    pub max_residual: f64,
    pub rtl: Option<RtlFrame>,
    /// The hierarchy merger top's run of the frame's merges, back to back
    /// on one top (None when it ran on none).
    pub merger: Option<MergerRtlFrame>,
    pub rays: RayCounts,
    pub node_tests_per_ray: f64,
    /// Node tests per primary ray on the subsample: merged, separate, full rebuild.
    pub comparison: Option<Comparison>,
    pub mismatches: u64,
    pub simulated: Vec<String>,
    pub skipped: Vec<String>,
    pub image: String,
    pub heat_map: String,
    pub seconds: StageSeconds,
}

/// Wall time per stage.
#[derive(Serialize, Clone, Copy, Default)]
pub struct StageSeconds {
    /// Frames::step: builds, translations, merge.
    pub step: f64,
    pub check: f64,
    pub rtl: f64,
    pub trace: f64,
    pub compare: f64,
    pub write: f64,
}

pub(crate) fn bar(options: &Options, what: String) -> ProgressBar {
    let b = ProgressBar::new(0);
    if options.progress {
        b.set_style(
            ProgressStyle::with_template("{prefix:>22} [{bar:30}] {pos}/{len} {elapsed}")
                .expect("a valid template")
                .progress_chars("=> "),
        );
        b.set_prefix(what);
    } else {
        b.set_draw_target(ProgressDrawTarget::hidden());
    }
    b
}

/// The objects of frame `k`. Without translation a placement is baked into
/// the vertices (a new mesh whenever the offset changes, so Frames rebuilds
/// the object) and the offset handed on is zero.
pub(super) fn frame_objects(
    scene: &Scene,
    k: usize,
    baked: &mut [Option<(DVec3, Arc<Mesh>)>],
) -> Vec<FrameObject> {
    scene
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| {
            let offset = o.offsets[k];
            if scene.effects.translation {
                return FrameObject {
                    id: Scene::object_id(i),
                    motion: o.motion,
                    mesh: o.mesh.clone(),
                    offset,
                };
            }
            let mesh = match &baked[i] {
                Some((at, m)) if *at == offset => m.clone(),
                _ => {
                    let m = Arc::new(Mesh {
                        vertices: o
                            .mesh
                            .vertices
                            .iter()
                            .map(|v| (v.as_dvec3() + offset).as_vec3())
                            .collect(),
                        triangles: o.mesh.triangles.clone(),
                    });
                    baked[i] = Some((offset, m.clone()));
                    m
                }
            };
            FrameObject {
                id: Scene::object_id(i),
                motion: o.motion,
                mesh,
                offset: DVec3::ZERO,
            }
        })
        .collect()
}

/// The objects of frame 0 `objs` whose scene object names a saved
/// hierarchy (SPEC 16): each file is loaded and checked and given to
/// `frames` for the object's first build; with `save`, a missing file is
/// built and saved, else the object is built as usual. Returns a line per
/// object saying which.
pub(super) fn provide_saved(
    scene: &Scene,
    frames: &mut Frames,
    objs: &[FrameObject],
    save: bool,
) -> Result<Vec<String>, String> {
    let mut lines = Vec::new();
    for (i, (o, fo)) in scene.objects.iter().zip(objs).enumerate() {
        let Some(file) = &o.hierarchy else { continue };
        if !save && std::fs::symlink_metadata(file).is_err() {
            continue;
        }
        let (g, p) = (&scene.grid, &scene.params);
        let (h, how) = golden::saved::load_or_build(file, &fo.mesh, g, p, fo.id)
            .map_err(|e| format!("objects[{i}].hierarchy ({}): {e}", o.name))?;
        lines.push(match how {
            Provenance::Loaded => format!(
                "{}: hierarchy loaded from {} (checked), not built",
                o.name,
                file.display()
            ),
            Provenance::Saved => format!(
                "{}: hierarchy built and saved to {}",
                o.name,
                file.display()
            ),
        });
        frames.provide(fo.id, h);
    }
    Ok(lines)
}

/// Runs every frame of `scene`.
pub fn run(scene: &Scene, options: &Options) -> Result<RunReport, String> {
    let mut run = Run::new(scene, options)?;
    for k in 0..scene.frames as usize {
        run.frame(k)?;
    }
    run.finish()
}

/// A run in progress: what it keeps from frame to frame (the world, the
/// RTL models built so far, the last frame's rays), so a frame redoes only
/// what changed. [`run`] drives it over every frame; a caller may drive it
/// frame by frame with [`Run::frame`] and end with [`Run::finish`].
pub struct Run<'a> {
    scene: &'a Scene,
    options: &'a Options,
    started: Instant,
    pub(super) frames: Frames,
    ids: Vec<u8>,
    /// Per object, its mesh with the placement baked in (scenes without
    /// translation), kept while the placement holds.
    baked: Vec<Option<(DVec3, Arc<Mesh>)>>,
    translate_rtl: Option<TranslateRtl>,
    rtl_info: RtlInfo,
    pub(super) merges: MergeStage<'a>,
    outs: Vec<FrameOut>,
    last_traced: Option<(Traced, Option<Comparison>)>,
    mismatches: u64,
}

/// What a frame prints: lines of what was simulated and what was skipped.
#[derive(Default)]
struct Said {
    simulated: Vec<String>,
    skipped: Vec<String>,
}

impl<'a> Run<'a> {
    /// A run of `scene` before its first frame.
    pub fn new(scene: &'a Scene, options: &'a Options) -> Result<Self, String> {
        let fx = &scene.effects;
        let frames = Frames::with_groups(scene.params, scene.grid, fx.merge, scene.groups.clone())
            .map_err(|e| e.to_string())?;
        let rtl_info = RtlInfo {
            translation: if !fx.translation {
                "not used by the scene: no translation unit generated or built".into()
            } else if !options.rtl {
                "disabled (--no-rtl)".into()
            } else {
                "not needed (no placement to determine)".into()
            },
            translation_build_seconds: 0.0,
            merge: if options.rtl {
                "not needed (no merge redone)".into()
            } else {
                "disabled (--no-rtl)".into()
            },
            merger: if !options.rtl {
                "disabled (--no-rtl)".into()
            } else if scene.groups.iter().all(|g| g.len() < 2) {
                "not used by the scene: nothing to merge, no merger generated or built".into()
            } else {
                "not needed (no merge redone)".into()
            },
            engine: options.engine,
            merger_store: options.merger_store.label(),
        };
        let run = Run {
            scene,
            options,
            started: Instant::now(),
            frames,
            ids: (0..scene.objects.len()).map(Scene::object_id).collect(),
            baked: vec![None; scene.objects.len()],
            translate_rtl: None,
            rtl_info,
            merges: MergeStage {
                scene,
                options,
                rtl: MergeRtl::new(options.engine),
                merger: MergerRtl::new(
                    options.engine,
                    options.merger_store,
                    scene.effects.translation,
                ),
            },
            outs: Vec::new(),
            last_traced: None,
            mismatches: 0,
        };
        run.say(format!(
            "scene {}: {} objects, {} frames, {}x{}, D={} Q={}",
            scene.name,
            scene.objects.len(),
            scene.frames,
            scene.width,
            scene.height,
            scene.params.max_lod,
            scene.params.quant_bits,
        ));
        Ok(run)
    }

    fn say(&self, s: String) {
        if self.options.narrate {
            eprintln!("{s}");
        }
    }

    /// Frame `k` (frames run in order from 0): the world brought to it,
    /// its merges, the translation unit on the placements that changed, its
    /// rays (or the last frame's, when nothing changed) and its images.
    pub fn frame(&mut self, k: usize) -> Result<&FrameOut, String> {
        let (scene, options) = (self.scene, self.options);
        let mut secs = StageSeconds::default();
        let mut said = Said::default();
        let objs = frame_objects(scene, k, &mut self.baked);
        if k == 0 {
            let lines = provide_saved(scene, &mut self.frames, &objs, true)?;
            said.simulated.extend(lines);
        }

        let t = Instant::now();
        let step_bar = bar(options, format!("frame {k} hierarchies"));
        step_bar.set_length(1);
        let rep: FrameReport = self
            .frames
            .step(&objs)
            .map_err(|e| format!("frame {k}: {e}"))?;
        step_bar.finish_and_clear();
        secs.step = t.elapsed().as_secs_f64();
        describe_actions(scene, &rep, &mut said.simulated, &mut said.skipped);
        let changed = rep.merged() || rep.objects.values().any(|&a| a != ObjectAction::Reused);

        let (groups, merger) = self.merges.run(
            k,
            &self.frames,
            &rep,
            &mut Lines {
                simulated: &mut said.simulated,
                skipped: &mut said.skipped,
            },
            &mut secs,
            &mut self.rtl_info,
        )?;
        let moved: Vec<u8> = rep
            .objects
            .iter()
            .filter(|(_, &a)| a != ObjectAction::Reused)
            .map(|(&id, _)| id)
            .collect();
        let max_residual = self.max_residual(&moved);
        let rtl_frame = self.translate(k, &moved, &mut said, &mut secs)?;
        let (traced, comparison) = self.trace(k, &rep, changed, &mut said, &mut secs)?;
        let (image, heat) = self.write_images(k, &traced, &mut secs)?;

        let rays = traced.rays.primary + traced.rays.shadow + traced.rays.reflection;
        let mismatches = rtl_frame.as_ref().map_or(0, |r| r.mismatches)
            + groups
                .iter()
                .filter_map(|g| g.merge_rtl.as_ref())
                .map(|r| r.mismatches)
                .sum::<u64>()
            + merger.as_ref().map_or(0, |t| t.mismatches)
            + comparison.as_ref().map_or(0, Comparison::faults);
        self.mismatches += mismatches;
        let out = FrameOut {
            frame: k as u32,
            actions: rep
                .objects
                .iter()
                .map(|(&id, &a)| (scene.objects[id as usize].name.clone(), a))
                .collect(),
            built: rep.count(ObjectAction::Built),
            rebuilt: rep.count(ObjectAction::Rebuilt),
            moved: rep.count(ObjectAction::Moved),
            retranslated: rep.count(ObjectAction::Retranslated),
            reused: rep.count(ObjectAction::Reused),
            merged: rep.merged(),
            nodes_created: groups.iter().map(|g| g.nodes_created).sum(),
            merged_nodes: groups.iter().map(|g| g.merged_nodes).sum(),
            groups,
            max_residual,
            rtl: rtl_frame,
            merger,
            rays: traced.rays,
            node_tests_per_ray: traced.stats.node_tests as f64 / rays.max(1) as f64,
            comparison: comparison.clone(),
            mismatches,
            simulated: said.simulated,
            skipped: said.skipped,
            image: image.display().to_string(),
            heat_map: heat.display().to_string(),
            seconds: secs,
        };
        self.say(format!("frame {k}:"));
        for s in &out.simulated {
            self.say(format!("  simulated: {s}"));
        }
        for s in &out.skipped {
            self.say(format!("  skipped:   {s}"));
        }
        self.outs.push(out);
        self.last_traced = Some((traced, comparison));
        Ok(self.outs.last().expect("pushed above"))
    }

    /// The largest placement residual (world units) over the objects
    /// `moved` this frame.
    fn max_residual(&self, moved: &[u8]) -> f64 {
        let mut max: f64 = 0.0;
        for &id in moved {
            let o = self.frames.world.object(id).expect("placed this frame");
            for a in Axis::ALL {
                max = max.max(o.determined.residual.value_f64(a).abs() * self.scene.grid.unit);
            }
        }
        max
    }

    /// The translation unit's RTL on the placements determined this frame
    /// (`moved`), built on first use; `None` with the reason said when the
    /// scene, the options or the frame call for none.
    fn translate(
        &mut self,
        k: usize,
        moved: &[u8],
        said: &mut Said,
        secs: &mut StageSeconds,
    ) -> Result<Option<RtlFrame>, String> {
        let (scene, options) = (self.scene, self.options);
        let why_not = if !scene.effects.translation {
            Some("translation unit: the scene uses no translation (placements baked into vertices)")
        } else if !options.rtl {
            Some("translation unit RTL: --no-rtl")
        } else if moved.is_empty() {
            Some("translation unit RTL: no placement changed, table entries reused")
        } else {
            None
        };
        if let Some(why) = why_not {
            said.skipped.push(why.into());
            return Ok(None);
        }
        let t = Instant::now();
        if self.translate_rtl.is_none() {
            let b = bar(options, "build translate RTL".into());
            b.set_length(1);
            let unit = TranslateRtl::build(&scene.params, options.engine)?;
            b.finish_and_clear();
            let engine = options.engine.label();
            self.rtl_info.translation = format!("built ({engine}), {:.1} s", unit.build_seconds);
            self.rtl_info.translation_build_seconds = unit.build_seconds;
            said.simulated.push(format!(
                "translation unit RTL generated and built with {engine} ({:.1} s, cached by content)",
                unit.build_seconds
            ));
            self.translate_rtl = Some(unit);
        }
        let world = &self.frames.world;
        let placed: Vec<Placed> = moved
            .iter()
            .map(|&id| {
                let o = world.object(id).expect("placed this frame");
                Placed {
                    id,
                    hierarchy: world.store.get(id).expect("in the store"),
                    grid_units: Axis::ALL.map(|a| o.placement.value_f64(a)),
                    translation: o.determined.translation,
                }
            })
            .collect();
        let unit = self.translate_rtl.as_mut().expect("built above");
        let b = bar(options, format!("frame {k} translate RTL"));
        b.set_length(1);
        let r = unit.run_frame(&placed)?;
        b.finish_and_clear();
        said.simulated.push(format!(
            "translation unit RTL: {} determine + {} apply transactions, {} cycles, {} mismatches",
            r.determine, r.apply, r.cycles, r.mismatches
        ));
        secs.rtl += t.elapsed().as_secs_f64();
        Ok(Some(r))
    }

    /// The frame's rays through its merged hierarchies, and the comparison
    /// with the separate hierarchies and a full rebuild; the last frame's
    /// when nothing `changed`.
    fn trace(
        &mut self,
        k: usize,
        rep: &FrameReport,
        changed: bool,
        said: &mut Said,
        secs: &mut StageSeconds,
    ) -> Result<(Traced, Option<Comparison>), String> {
        let (scene, options, fx) = (self.scene, self.options, &self.scene.effects);
        let out = match (&self.last_traced, changed) {
            (Some(last), false) => {
                said.skipped.push(format!(
                    "trace: nothing changed since frame {}, its image and counts reused",
                    k - 1
                ));
                last.clone()
            }
            _ => {
                let world = &self.frames.world;
                let instances = world
                    .group_instances(&rep.merged_ids(), &self.ids)
                    .map_err(|e| format!("frame {k}: {e}"))?;
                let ts = world
                    .trace_scene(&instances, &rep.roots())
                    .map_err(|e| format!("frame {k}: {e}"))?;
                let b = bar(options, format!("frame {k} trace"));
                let traced = trace_frame(scene, &ts, &b);
                b.finish_and_clear();
                secs.trace = traced.seconds;
                said.simulated.push(ray_line(scene, &traced.rays));
                let comparison = if fx.primary {
                    let b = bar(options, format!("frame {k} compare"));
                    let c = compare(scene, world, &self.ids, &ts, options.verify, &b)
                        .map_err(|e| format!("frame {k}: {e}"))?;
                    b.finish_and_clear();
                    secs.compare = c.seconds;
                    said.simulated.push(format!(
                        "comparison on 1 primary ray in {} ({} rays): merged, separate, full rebuild",
                        SUBSAMPLE * SUBSAMPLE,
                        c.rays
                    ));
                    if let Some(o) = &c.oracle {
                        said.simulated.push(o.to_string());
                    }
                    Some(c)
                } else {
                    None
                };
                (traced, comparison)
            }
        };
        if !fx.primary {
            said.skipped
                .push("primary rays: not asked for (no image traced)".into());
        }
        if !fx.shadow {
            said.skipped.push("shadow rays: not asked for".into());
        }
        if fx.reflection_depth == 0 {
            said.skipped.push("reflections: not asked for".into());
        }
        Ok(out)
    }

    /// Frame `k`'s image and heat map: the paths the report names (in
    /// `options.out`), written into `options.write_to`.
    fn write_images(
        &self,
        k: usize,
        traced: &Traced,
        secs: &mut StageSeconds,
    ) -> Result<(PathBuf, PathBuf), String> {
        let t = Instant::now();
        let image = self.options.out.join(format!("frame_{k:03}.png"));
        let heat = self.options.out.join(format!("heat_{k:03}.png"));
        self.write_pair(&image, &heat, traced)?;
        secs.write = t.elapsed().as_secs_f64();
        Ok((image, heat))
    }

    fn write_pair(&self, image: &Path, heat: &Path, traced: &Traced) -> Result<(), String> {
        if !self.options.images {
            return Ok(());
        }
        let (w, h) = (self.scene.width, self.scene.height);
        let at = |p: &Path| {
            self.options
                .write_to
                .join(p.file_name().expect("a file name"))
        };
        write_png(&at(image), w, h, &traced.rgb)?;
        write_png(&at(heat), w, h, &heat_rgb(&traced.node_tests))
    }

    /// The report of every frame run, with the last frame's image written
    /// as `image.png` and `heat.png`.
    pub fn finish(self) -> Result<RunReport, String> {
        let (scene, fx) = (self.scene, &self.scene.effects);
        let (traced, _) = self
            .last_traced
            .as_ref()
            .ok_or("the run has no frame: run frame 0 before finishing")?;
        let image = self.options.out.join("image.png");
        let heat = self.options.out.join("heat.png");
        self.write_pair(&image, &heat, traced)?;
        Ok(RunReport {
            scene: scene.name.clone(),
            params: scene.params,
            frame_count: scene.frames,
            objects: scene
                .objects
                .iter()
                .enumerate()
                .map(|(i, o)| ObjectInfo {
                    id: Scene::object_id(i),
                    name: o.name.clone(),
                    motion: o.motion,
                    triangles: o.mesh.len() as u64,
                })
                .collect(),
            effects: EffectsInfo {
                translation: fx.translation,
                merge_mode: format!("{:?}", fx.merge),
                upper_build: fx.upper_build,
                primary: fx.primary,
                shadow: fx.shadow,
                reflection_depth: fx.reflection_depth,
                clip_distance: fx.clip_distance,
            },
            image: ImageSummary {
                width: scene.width,
                height: scene.height,
                rays: traced.rays.primary,
                hits: traced.rays.primary_hits,
                image: image.display().to_string(),
                heat_map: heat.display().to_string(),
            },
            rtl: self.rtl_info,
            frames: self.outs,
            mismatches: self.mismatches,
            seconds: self.started.elapsed().as_secs_f64(),
        })
    }
}

fn describe_actions(
    scene: &Scene,
    rep: &FrameReport,
    simulated: &mut Vec<String>,
    skipped: &mut Vec<String>,
) {
    for (&id, &a) in &rep.objects {
        let name = &scene.objects[id as usize].name;
        match a {
            ObjectAction::Built => simulated.push(format!("{name}: hierarchy built and placed")),
            ObjectAction::Rebuilt => simulated.push(format!(
                "{name}: hierarchy rebuilt ({})",
                if scene.effects.translation {
                    "its mesh changed"
                } else {
                    "moved, and the scene uses no translation"
                }
            )),
            ObjectAction::Moved => simulated.push(format!(
                "{name}: moved by a fraction of a voxel, new residual: local geometry rebuilt, new translation determined"
            )),
            ObjectAction::Retranslated => simulated.push(format!(
                "{name}: moved by whole voxels, residual unchanged: new translation determined (hierarchy reused, not rebuilt)"
            )),
            ObjectAction::Reused => skipped.push(format!(
                "{name}: unchanged, hierarchy and translation reused"
            )),
        }
        if let Some(f) = rep.fallbacks.get(&id) {
            simulated.push(format!(
                "{name}: translated at LOD {}, not LOD {}: {}",
                f.settled_lod, f.refused_lod, f.reason
            ));
        }
    }
}

fn ray_line(scene: &Scene, r: &RayCounts) -> String {
    let mut s = format!(
        "trace: {} primary rays ({} hits)",
        r.primary, r.primary_hits
    );
    if scene.effects.shadow {
        s += &format!(", {} shadow rays ({} blocked)", r.shadow, r.shadowed);
    }
    if scene.effects.reflection_depth > 0 {
        s += &format!(
            ", {} reflection rays (depth <= {})",
            r.reflection, scene.effects.reflection_depth
        );
    }
    s
}
