//! `hiermerge run [SCENE]`: the main job (SPEC.md section 12), a thin
//! command over the library's [`hiermerge::run`]: the arguments, the output
//! folder swapped in whole when the run is complete, and the report.

use std::path::PathBuf;

use golden::merge::merger::store_port::StorePort;
use golden::scene::{Scene, MAX_IMAGE_SIDE};
use hiermerge::run::{
    closing_table, preflight, run, MergerStore, Options, RunEngine, PATCH_FROM_VAR, PATCH_TO_VAR,
};

use crate::report::{emit, CmdResult};

/// The embedded default scene (`scenes/default.json`).
pub const DEFAULT_SCENE: &str = include_str!("../../scenes/default.json");

#[derive(clap::Args)]
pub struct Args {
    /// A scene file (JSON, SPEC.md section 12); the embedded default scene when absent.
    scene: Option<PathBuf>,
    /// Folder for the images and the report.
    #[arg(long, default_value = "out/run")]
    out: PathBuf,
    /// Image width in pixels (overrides the scene's).
    #[arg(long)]
    width: Option<u32>,
    /// Image height in pixels (overrides the scene's).
    #[arg(long)]
    height: Option<u32>,
    /// Do not build or simulate RTL (the run says so); golden model only.
    #[arg(long)]
    no_rtl: bool,
    /// The simulator of every unit: `verilator` or `ir` (rtl-gen's IR
    /// simulator: nothing to build, slower per cycle).
    #[arg(long, default_value = "verilator")]
    engine: String,
    /// How the hierarchy merger top reaches the store: `shared` or
    /// `shared:T` (the default, `shared:3`): one read port for every unit,
    /// a tag FIFO of 2^T reads in flight, answered from the store image of
    /// the merge's inputs by a store model after --store-latency clocks;
    /// `per-unit`: every fetcher and the writer with its own read streams,
    /// their answers precomputed by golden.
    #[arg(long = "store-port", value_parser = crate::cmd::cosim::parse_store_port)]
    store_port: Option<StorePort>,
    /// A shared store port's latency: clocks from a read taken to its
    /// answer, at the earliest (default 1).
    #[arg(long = "store-latency")]
    store_latency: Option<u64>,
    /// Print one JSON object on stdout (no progress bars).
    #[arg(long)]
    json: bool,
    /// Judge the merged hierarchy's hits on the compared rays by the independent binary64
    /// oracle over the triangles at their requested positions (SPEC 6.10); faults count as
    /// mismatches.
    #[arg(long)]
    verify: bool,
}

pub fn main(a: Args) -> CmdResult {
    let mut scene = match &a.scene {
        Some(path) => Scene::load(path).map_err(|e| e.to_string())?,
        None => Scene::parse(
            DEFAULT_SCENE,
            "default scene (embedded)",
            std::path::Path::new("."),
        )
        .map_err(|e| e.to_string())?,
    };
    if a.scene.is_none() {
        scene.name = "default (embedded)".into();
    }
    for (what, v) in [("--width", a.width), ("--height", a.height)] {
        if let Some(v) = v {
            if !(1..=MAX_IMAGE_SIDE).contains(&v) {
                return Err(format!("{what} {v}: expected 1..={MAX_IMAGE_SIDE} pixels"));
            }
        }
    }
    let file = a
        .scene
        .as_ref()
        .map_or("default scene (embedded)".to_string(), |p| {
            p.display().to_string()
        });
    preflight::check(&scene, &file).map_err(|e| e.to_string())?;
    let merger_store = merger_store(&a)?;
    scene.width = a.width.unwrap_or(scene.width);
    scene.height = a.height.unwrap_or(scene.height);
    // A fresh folder, put in place of --out only when the run is complete
    // (SPEC.md section 15): an interrupted run leaves the previous output.
    refuse_foreign_folder(&a.out)?;
    let staging = golden::output::AtomicDir::create(&a.out)?;
    let options = Options {
        out: a.out.clone(),
        write_to: staging.path().to_path_buf(),
        rtl: !a.no_rtl,
        engine: RunEngine::parse(&a.engine)?,
        progress: !a.json && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        narrate: !a.json,
        verify: a.verify,
        images: true,
        merger_store,
    };
    let report = run(&scene, &options)?;
    let json = serde_json::to_string_pretty(&report).map_err(|e| e.to_string())?;
    let report_path = a.out.join("report.json");
    golden::output::write_atomic(&staging.path().join("report.json"), json.as_bytes())?;
    staging.commit()?;
    let mismatches = report.mismatches;
    emit(a.json, &report, |r| {
        println!();
        print!("{}", closing_table(r));
        println!(
            "wrote {} frames, {} and {}",
            r.frames.len(),
            r.image.image,
            report_path.display()
        );
    })?;
    if mismatches > 0 {
        return Err(format!(
            "{mismatches} mismatches (RTL against golden, or merged against separate hierarchies); \
             see {} (each frame's `simulated` lines and `first_mismatch` fields, decoded); \
             reproduce: {}",
            report_path.display(),
            reproduce(&a)
        ));
    }
    Ok(())
}

/// The command line that reruns `a` (the run is deterministic: the same
/// scene and flags give the same merges, beats and cycles).
fn reproduce(a: &Args) -> String {
    let mut line = String::new();
    for var in [PATCH_FROM_VAR, PATCH_TO_VAR] {
        if let Ok(v) = std::env::var(var) {
            // Shell-quoted: a patch's Verilog has quotes of its own (`150'd1`).
            line += &format!("{var}='{}' ", v.replace('\'', r"'\''"));
        }
    }
    line += "hiermerge run";
    if let Some(scene) = &a.scene {
        line += &format!(" {}", scene.display());
    }
    line += &format!(" --engine {}", a.engine);
    for (flag, v) in [("--width", a.width), ("--height", a.height)] {
        if let Some(v) = v {
            line += &format!(" {flag} {v}");
        }
    }
    if a.verify {
        line += " --verify";
    }
    if let Some(port) = a.store_port {
        let name = MergerStore { port, latency: 1 }.port_name();
        line += &format!(" --store-port {name}");
    }
    if let Some(l) = a.store_latency {
        line += &format!(" --store-latency {l}");
    }
    line
}

/// The merger top's store port from `--store-port` and `--store-latency`
/// (one shared port answering the next clock when neither is given).
fn merger_store(a: &Args) -> Result<MergerStore, String> {
    let d = MergerStore::default();
    let port = a.store_port.unwrap_or(d.port);
    match (port, a.store_latency) {
        (StorePort::PerUnit, Some(_)) => {
            Err("--store-latency applies to a shared store port (--store-port shared[:T]) only: per-unit ports get golden's answers as streams".into())
        }
        (_, Some(0)) => Err("--store-latency 0: expected 1 or more clocks".into()),
        (port, latency) => Ok(MergerStore {
            port,
            latency: latency.unwrap_or(d.latency),
        }),
    }
}

/// The whole `--out` folder is replaced, so it must be empty or an earlier
/// run's output (it holds `report.json`): a folder of other files is never
/// deleted by mistake.
fn refuse_foreign_folder(out: &std::path::Path) -> Result<(), String> {
    let Ok(mut items) = std::fs::read_dir(out) else {
        return Ok(());
    };
    if items.next().is_none() || out.join("report.json").is_file() {
        return Ok(());
    }
    Err(format!(
        "{}: the folder holds files but no report.json of an earlier run; \
         refusing to replace it (run replaces --out whole): choose an empty or new folder",
        out.display()
    ))
}
