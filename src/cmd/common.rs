//! Options and steps shared by several subcommands.

use std::path::{Path, PathBuf};

use golden::build::{build_parallel, GridMap};
use golden::mesh::Mesh;
use golden::store::Hierarchy;
use golden::Params;
use serde::Serialize;

/// The grid parameters every building command takes.
#[derive(clap::Args, Clone, Debug)]
pub struct GridOpts {
    /// D: the deepest octree level (1..=31).
    #[arg(long = "max-lod", default_value_t = Params::default().max_lod)]
    pub max_lod: u8,
    /// Q: bits per quantized box bound (0..=16; 0: boxes are voxels).
    #[arg(long = "quant-bits", default_value_t = Params::default().quant_bits)]
    pub quant_bits: u8,
    /// Bits of node, reference and primitive indices (1..=32).
    #[arg(long = "index-bits", default_value_t = Params::default().index_bits)]
    pub index_bits: u8,
    /// Bits of a hierarchy id (1..=8).
    #[arg(long = "hier-bits", default_value_t = Params::default().hier_bits)]
    pub hier_bits: u8,
}

impl GridOpts {
    pub fn params(&self) -> Result<Params, String> {
        Params::new(
            self.max_lod,
            self.quant_bits,
            self.index_bits,
            self.hier_bits,
        )
        .map_err(|e| e.to_string())
    }
}

/// Loads a mesh, with the file named in any error; a mesh needs a triangle.
pub fn load_mesh(path: &Path) -> Result<Mesh, String> {
    let mesh = Mesh::load(path).map_err(|e| e.to_string())?;
    if mesh.triangles.is_empty() {
        return Err(format!(
            "{}: the mesh has no triangles: expected at least one face",
            path.display()
        ));
    }
    Ok(mesh)
}

/// One grid for every local frame and the scene: it holds each mesh where
/// it is and where `offsets` (world units) place it, with room to spare.
pub fn placement_grid(
    meshes: &[Mesh],
    offsets: &[glam::DVec3],
    params: &Params,
) -> Result<GridMap, String> {
    let (mut lo, mut hi) = (
        glam::DVec3::splat(f64::INFINITY),
        glam::DVec3::splat(f64::NEG_INFINITY),
    );
    for (m, off) in meshes.iter().zip(offsets) {
        let (l, h) = m.bounds();
        let (l, h) = (l.as_dvec3(), h.as_dvec3());
        lo = lo.min(l).min(l + *off);
        hi = hi.max(h).max(h + *off);
    }
    let (lo, hi) = (lo.as_vec3(), hi.as_vec3());
    if !(lo.is_finite() && hi.is_finite() && (hi - lo).is_finite()) {
        return Err(
            "--translate: the placed meshes span more than binary32 world coordinates can hold"
                .into(),
        );
    }
    let fitted = GridMap::fit(lo, hi, params);
    // Doubling the unit leaves room for voxel-aligned rounding of placements.
    Ok(GridMap {
        origin: fitted.origin - (hi - lo).as_dvec3() * 0.5,
        unit: fitted.unit * 2.0,
    })
}

/// A hierarchy built over one mesh, with the grid map that placed it.
pub struct Built {
    pub mesh: Mesh,
    pub grid: GridMap,
    pub hierarchy: Hierarchy,
    pub seconds: f64,
}

/// Builds `mesh` into a grid fitted to its bounds, timing only the build,
/// on every core (rayon's global pool; `RAYON_NUM_THREADS=1` for one
/// thread): the same hierarchy as the one-thread build, bit for bit.
pub fn build_fitted(path: PathBuf, mesh: Mesh, params: &Params, id: u8) -> Result<Built, String> {
    let (lo, hi) = mesh.bounds();
    let grid = GridMap::fit(lo, hi, params);
    let start = std::time::Instant::now();
    let hierarchy =
        build_parallel(&mesh, &grid, params, id).map_err(|e| format!("{}: {e}", path.display()))?;
    let seconds = start.elapsed().as_secs_f64();
    Ok(Built {
        mesh,
        grid,
        hierarchy,
        seconds,
    })
}

/// The shape of a hierarchy: what `build` reports.
#[derive(Serialize, Clone, Debug)]
pub struct Shape {
    /// Node count at each LOD, index = LOD, from 0 to the deepest node.
    pub nodes_per_lod: Vec<u64>,
    pub nodes: u64,
    pub inner: u64,
    pub leaves: u64,
    pub top_lod: u8,
    pub roots: u32,
    /// Levels from the top to the deepest node, inclusive.
    pub depth: u32,
}

impl Shape {
    pub fn of(h: &Hierarchy) -> Shape {
        let deepest = h.nodes.iter().map(|n| n.voxel.lod).max().unwrap_or(0);
        let mut nodes_per_lod = vec![0u64; deepest as usize + 1];
        let mut leaves = 0;
        for n in &h.nodes {
            nodes_per_lod[n.voxel.lod as usize] += 1;
            leaves += n.leaf as u64;
        }
        Shape {
            nodes_per_lod,
            nodes: h.nodes.len() as u64,
            inner: h.nodes.len() as u64 - leaves,
            leaves,
            top_lod: h.top_lod,
            roots: h.root_count,
            depth: (deepest - h.top_lod.min(deepest)) as u32 + 1,
        }
    }
}

/// The configuration flags of a generated unit, shared by `gen`, `vectors`
/// and `cosim`: the grid, and each unit's own parameters.
#[derive(clap::Args, Clone, Debug)]
pub struct UnitOpts {
    #[command(flatten)]
    pub grid: GridOpts,
    /// Translation unit: entries of the translation table (default: one per hierarchy id).
    #[arg(long = "table-depth")]
    pub table_depth: Option<u32>,
    /// Translation unit: binary64 placements as well as binary32.
    #[arg(long)]
    pub binary64: bool,
    /// Merging module: number of merged inputs (default 4).
    #[arg(long)]
    pub inputs: Option<usize>,
    /// Merging module: how it chooses the merging level, the one mode it builds:
    /// overlap[:N/D] (default overlap:1/2), fixed:L, below-top:K, proportion:N/D or
    /// per-node[:N/D].
    #[arg(long)]
    pub mode: Option<String>,
}

/// `--mode` when not given.
pub const DEFAULT_MODE: &str = "overlap:1/2";

/// A flag of some units only: its spelling, whether it was given, and the
/// units (as `--unit` names them) it applies to.
pub type UnitFlag = (&'static str, bool, &'static [&'static str]);

/// Refuses the first of `flags` given that does not apply to `unit`,
/// naming it and the units it applies to: a flag another unit takes is
/// never silently ignored.
pub fn refuse_flags_of_other_units(unit: &str, flags: &[UnitFlag]) -> Result<(), String> {
    for &(flag, given, units) in flags {
        if given && !units.contains(&unit) {
            let to: Vec<String> = units.iter().map(|u| format!("--unit {u}")).collect();
            return Err(format!(
                "{flag} applies to {} only, not to --unit {unit}",
                to.join(" and ")
            ));
        }
    }
    Ok(())
}

impl UnitOpts {
    /// The unit parameters of these flags, each with the units it
    /// configures (the grid configures every unit).
    pub fn unit_flags(&self) -> [UnitFlag; 4] {
        const TRANSLATE: &[&str] = &["translate"];
        const TABLE: &[&str] = &["translate", "hierarchy"];
        const MERGING: &[&str] = &["merge-module", "merger", "hierarchy"];
        [
            ("--table-depth", self.table_depth.is_some(), TABLE),
            ("--binary64", self.binary64, TRANSLATE),
            ("--inputs", self.inputs.is_some(), MERGING),
            ("--mode", self.mode.is_some(), MERGING),
        ]
    }

    /// `--mode`, or its default.
    pub fn mode(&self) -> &str {
        self.mode.as_deref().unwrap_or(DEFAULT_MODE)
    }

    /// `--inputs`, or its default.
    pub fn inputs(&self) -> usize {
        self.inputs
            .unwrap_or(golden::merge::merge_module::MergeDesign::default().inputs)
    }

    /// The translation unit these flags ask for, validated.
    pub fn translate_design(&self) -> Result<golden::translate::model::TranslateDesign, String> {
        let params = self.grid.params()?;
        let design = golden::translate::model::TranslateDesign {
            unit: golden::translate::TranslateUnitConfig {
                params,
                table_depth: self.table_depth.unwrap_or(params.hier_capacity() as u32),
            },
            binary64: self.binary64,
        };
        design
            .validate()
            .map_err(|e| format!("translation unit configuration: {e}"))?;
        Ok(design)
    }

    /// The merging module these flags ask for, validated.
    pub fn merge_design(&self) -> Result<golden::merge::merge_module::MergeDesign, String> {
        let params = self.grid.params()?;
        let design = golden::merge::merge_module::MergeDesign {
            params,
            inputs: self.inputs(),
            mode: super::merge::parse_mode(self.mode()).map_err(|e| format!("--mode {e}"))?,
            ..Default::default()
        };
        design
            .validate()
            .map_err(|e| format!("merging module configuration: {e}"))?;
        Ok(design)
    }
}

/// The value of a seed or count flag: an unsigned integer. A negative
/// number is said to be one (the standard parser's "invalid digit found in
/// string" does not say what was wrong with `--seed -1`).
pub fn unsigned<T: TryFrom<u64>>(s: &str) -> Result<T, String> {
    let expected = "expected an unsigned integer (0, 1, 2, ...)";
    if s.trim_start().starts_with('-') {
        return Err(format!("a negative number: {expected}"));
    }
    let v: u64 = s.trim().parse().map_err(|_| expected.to_string())?;
    T::try_from(v).map_err(|_| format!("{v} is too large for this flag"))
}
