//! `hiermerge run [SCENE]`: the main job.
//!
//! Today: builds one hierarchy per object of the embedded default scene,
//! traces one primary ray per pixel through all of them, and writes a shaded
//! image, a heat map of node tests per pixel and a JSON report.

use std::path::PathBuf;
use std::time::Instant;

use glam::Vec3;
use golden::build::{build, GridMap};
use golden::camera::Camera;
use golden::mesh::Mesh;
use golden::store::Hierarchy;
use golden::trace::{closest_hit, Instance, TraceScene, TraceStats};
use serde::Serialize;

use super::common::{GridOpts, Shape};
use crate::image::{heat_rgb, write_png};
use crate::report::{emit, per_second, CmdResult};

#[derive(clap::Args)]
pub struct Args {
    /// A scene file (not yet supported: the embedded default scene is used when absent).
    scene: Option<PathBuf>,
    /// Folder for the images and the report.
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 320)]
    width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 240)]
    height: u32,
    #[command(flatten)]
    grid: GridOpts,
    /// Print one JSON object on stdout.
    #[arg(long)]
    json: bool,
}

/// One object of a scene.
struct Object {
    name: &'static str,
    mesh: Mesh,
}

/// The embedded default scene: a large static terrain and a few objects on it.
fn default_scene() -> (Vec<Object>, Camera) {
    use golden::scenes::{box_mesh, sphere, terrain, torus};
    let objects = vec![
        Object {
            name: "terrain",
            mesh: terrain(160, 7),
        },
        Object {
            name: "sphere",
            mesh: sphere(Vec3::new(0.3, 0.72, 0.35), 0.12, 24, 48),
        },
        Object {
            name: "torus",
            mesh: torus(Vec3::new(0.68, 0.7, 0.55), 0.12, 0.04, 48, 24),
        },
        Object {
            name: "crate",
            mesh: box_mesh(Vec3::new(0.45, 0.55, 0.72), Vec3::new(0.6, 0.7, 0.87)),
        },
    ];
    let camera = Camera {
        eye: Vec3::new(0.5, 1.25, -0.55),
        target: Vec3::new(0.5, 0.5, 0.5),
        up: Vec3::Y,
        fov_y_degrees: 50.0,
    };
    (objects, camera)
}

#[derive(Serialize)]
struct Report {
    scene: String,
    params: golden::Params,
    objects: Vec<ObjectReport>,
    image: ImageReport,
    seconds: Seconds,
}

#[derive(Serialize)]
struct ObjectReport {
    name: String,
    triangles: u64,
    #[serde(flatten)]
    shape: Shape,
}

#[derive(Serialize)]
struct ImageReport {
    width: u32,
    height: u32,
    rays: u64,
    hits: u64,
    node_tests_per_ray: f64,
    prim_tests_per_ray: f64,
    rays_per_second: f64,
    image: String,
    heat_map: String,
}

#[derive(Serialize)]
struct Seconds {
    build: f64,
    trace: f64,
}

pub fn main(a: Args) -> CmdResult {
    if let Some(s) = &a.scene {
        return Err(format!("{}: scene files are not supported yet; run without an argument for the embedded default scene", s.display()));
    }
    if a.width == 0 || a.height == 0 || a.width > 8192 || a.height > 8192 {
        return Err(format!(
            "image size {}x{}: expected 1..=8192 pixels on each side",
            a.width, a.height
        ));
    }
    let params = a.grid.params()?;
    let (objects, camera) = default_scene();
    if objects.len() as u64 > params.hier_capacity() {
        return Err(format!(
            "{} objects need more than --hier-bits {}",
            objects.len(),
            params.hier_bits
        ));
    }
    let (lo, hi) = objects.iter().map(|o| o.mesh.bounds()).fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(l, h), (ol, oh)| (l.min(ol), h.max(oh)),
    );
    let grid = GridMap::fit(lo, hi, &params);

    let start = Instant::now();
    let mut hierarchies: Vec<Hierarchy> = Vec::new();
    for (i, o) in objects.iter().enumerate() {
        hierarchies
            .push(build(&o.mesh, &grid, &params, i as u8).map_err(|e| format!("{}: {e}", o.name))?);
    }
    let build_seconds = start.elapsed().as_secs_f64();

    let instances: Vec<Instance> = hierarchies
        .iter()
        .zip(&objects)
        .map(|(h, o)| Instance::new(h, &o.mesh))
        .collect();
    let scene = TraceScene::new(grid, &instances).map_err(|e| e.to_string())?;
    let frame = trace_image(&scene, &objects, &camera, a.width, a.height);

    std::fs::create_dir_all(&a.out)
        .map_err(|e| format!("{}: cannot create the output folder: {e}", a.out.display()))?;
    let image_path = a.out.join("image.png");
    let heat_path = a.out.join("heat.png");
    write_png(&image_path, a.width, a.height, &frame.rgb)?;
    let heat = heat_rgb(&frame.node_tests);
    write_png(&heat_path, a.width, a.height, &heat)?;

    let rays = frame.node_tests.len() as u64;
    let report = Report {
        scene: "default (embedded)".into(),
        params,
        objects: objects
            .iter()
            .zip(&hierarchies)
            .map(|(o, h)| ObjectReport {
                name: o.name.into(),
                triangles: o.mesh.triangles.len() as u64,
                shape: Shape::of(h),
            })
            .collect(),
        image: ImageReport {
            width: a.width,
            height: a.height,
            rays,
            hits: frame.hits,
            node_tests_per_ray: frame.stats.node_tests as f64 / rays as f64,
            prim_tests_per_ray: frame.stats.prim_tests as f64 / rays as f64,
            rays_per_second: per_second(rays as f64, frame.seconds),
            image: image_path.display().to_string(),
            heat_map: heat_path.display().to_string(),
        },
        seconds: Seconds {
            build: build_seconds,
            trace: frame.seconds,
        },
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    let report_path = a.out.join("report.json");
    std::fs::write(&report_path, json).map_err(|e| format!("{}: {e}", report_path.display()))?;
    emit(a.json, &report, |r| {
        println!(
            "scene: {}  (D={} Q={})",
            r.scene, r.params.max_lod, r.params.quant_bits
        );
        for o in &r.objects {
            println!(
                "  {:<8} {:>7} triangles -> {:>7} nodes, top LOD {}, depth {}",
                o.name, o.triangles, o.shape.nodes, o.shape.top_lod, o.shape.depth
            );
        }
        let i = &r.image;
        println!(
            "traced {}x{} = {} primary rays: {} hits, {:.1} node tests/ray, {:.1} triangle tests/ray, {:.0} rays/s",
            i.width, i.height, i.rays, i.hits, i.node_tests_per_ray, i.prim_tests_per_ray, i.rays_per_second
        );
        println!(
            "build {:.3} s, trace {:.3} s",
            r.seconds.build, r.seconds.trace
        );
        println!(
            "wrote {}, {} and {}",
            i.image,
            i.heat_map,
            report_path.display()
        );
    })
}

/// A traced image: colours, node tests per pixel, totals.
struct Frame {
    rgb: Vec<u8>,
    node_tests: Vec<u64>,
    stats: TraceStats,
    hits: u64,
    seconds: f64,
}

/// One primary ray per pixel; a hit is shaded by its triangle's facing to a
/// fixed light, tinted per object, so the image shows the scene's shapes.
fn trace_image(scene: &TraceScene, objects: &[Object], camera: &Camera, w: u32, h: u32) -> Frame {
    let light = Vec3::new(-0.4, 1.0, -0.3).normalize();
    let tints = [
        Vec3::new(0.55, 0.75, 0.45),
        Vec3::new(0.9, 0.35, 0.3),
        Vec3::new(0.95, 0.8, 0.3),
        Vec3::new(0.6, 0.45, 0.3),
    ];
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    let mut node_tests = Vec::with_capacity((w * h) as usize);
    let mut stats = TraceStats::default();
    let mut hits = 0;
    let start = Instant::now();
    for py in 0..h {
        for px in 0..w {
            let ray = camera.primary_ray(px, py, w, h);
            let mut s = TraceStats::default();
            let colour = match closest_hit(&ray, scene, &mut s) {
                Some(hit) => {
                    hits += 1;
                    let mesh = &objects[hit.hier as usize].mesh;
                    let [a, b, c] = mesh.triangle(hit.prim as usize);
                    let mut n = (b - a).cross(c - a).normalize_or_zero();
                    if n.dot(ray.dir) > 0.0 {
                        n = -n;
                    }
                    let diffuse = n.dot(light).max(0.0);
                    tints[hit.hier as usize % tints.len()] * (0.2 + 0.8 * diffuse)
                }
                None => Vec3::new(0.6, 0.75, 0.95) * (1.0 - 0.3 * py as f32 / h as f32),
            };
            rgb.extend(
                colour
                    .to_array()
                    .map(|c| (c.clamp(0.0, 1.0) * 255.0).round() as u8),
            );
            node_tests.push(s.node_tests);
            stats += s;
        }
    }
    Frame {
        rgb,
        node_tests,
        stats,
        hits,
        seconds: start.elapsed().as_secs_f64(),
    }
}
