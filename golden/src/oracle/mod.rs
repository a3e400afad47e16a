//! The independent oracle of `--verify` (SPEC 6.10): golden's closest hits
//! judged against the triangles at their **requested** world positions in
//! binary64, traced by [`reference::ReferenceTracer`], with no translation,
//! no voxel grid and no hierarchy of golden's. Brute force over golden's own
//! geometry cannot see a placement that went wrong; this can.
//!
//! Golden and the oracle see the same ray and nearly the same triangles, so
//! they may disagree only within a stated error bound: where a ray passes
//! within that bound of an edge (grazing), or meets two surfaces within it
//! of each other (a tie). Any other disagreement is a fault.

pub mod reference;

use std::collections::BTreeMap;
use std::fmt;

use glam::DVec3;
use serde::Serialize;

use crate::geom::Ray;
use crate::mesh::Mesh;
use crate::trace::Hit;
use reference::ReferenceTracer;

/// Relative error of golden's binary32 geometry and kernels (SPEC 6.2, 6.6,
/// 7.10): the local geometry's vertices (rounded once to binary32), the
/// moved origin, the watertight test's edge functions and `t` each carry a
/// few binary32 ulps (`2^-24` relative) of the coordinates they work with:
/// the largest coordinate of the ray origin in the instance's frame plus the
/// largest of its vertices. `2^-20` allows sixteen ulps.
pub const KERNEL_REL: f64 = 1.0 / (1u64 << 20) as f64;

/// Relative rounding of the oracle's own binary64 world coordinates.
pub const WORLD_REL: f64 = 1.0 / (1u64 << 50) as f64;

/// Rays nearly parallel to a triangle: the cosine below which the bound
/// along the ray stops growing (`1 / 2^-10` times the distance bound).
const MIN_COSINE: f64 = 1.0 / 1024.0;

/// One hierarchy's triangles as golden traces them and as they were asked for.
#[derive(Clone, Copy, Debug)]
pub struct Part<'a> {
    /// The hierarchy id golden's hits name.
    pub hier: u8,
    /// The mesh as given, in its own frame, world units.
    pub source: &'a Mesh,
    /// Where it was asked to be: added to every source vertex, world units.
    pub offset: DVec3,
    /// What golden traces (the local geometry, triangle for triangle with `source`).
    pub traced: &'a Mesh,
    /// The translation golden applies to `traced`, world units.
    pub shift: DVec3,
}

/// One part's error terms (world units). They come from magnitudes alone,
/// never from how far golden's geometry is from the requested one: a bound
/// that measured that would excuse the very misplacement it must catch.
#[derive(Clone, Copy, Debug)]
struct Bound {
    shift: DVec3,
    /// Largest absolute coordinate of the traced (local) vertices.
    local_magnitude: f64,
    /// Largest absolute coordinate of the requested world vertices.
    world_magnitude: f64,
}

/// How golden's answer for one ray compares with the oracle's.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// Both miss, or both hit the same triangle with `t` within the bound.
    Agree,
    /// They differ, but the ray passes within the bound of an edge of a
    /// triangle involved, or of the ray's ends: both are right to within rounding.
    Grazing,
    /// Different triangles whose surfaces the ray meets within the bound of each other.
    Tie,
    /// Golden hits another triangle than the oracle's, by more than the bound.
    WrongTriangle,
    /// Only the oracle hits.
    Missed,
    /// Only golden hits.
    Extra,
    /// The same triangle, `t` off by more than the bound.
    TError,
}

impl Verdict {
    /// True for the verdicts that fail verification.
    pub fn is_fault(self) -> bool {
        matches!(
            self,
            Verdict::WrongTriangle | Verdict::Missed | Verdict::Extra | Verdict::TError
        )
    }
}

/// Counts over many rays.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct OracleSummary {
    /// Rays judged.
    pub rays: u64,
    /// Rays the oracle hits.
    pub oracle_hits: u64,
    /// Per verdict.
    pub agree: u64,
    /// See [`Verdict::Grazing`].
    pub grazing: u64,
    /// See [`Verdict::Tie`].
    pub ties: u64,
    /// See [`Verdict::WrongTriangle`].
    pub wrong_triangle: u64,
    /// See [`Verdict::Missed`].
    pub missed: u64,
    /// See [`Verdict::Extra`].
    pub extra: u64,
    /// See [`Verdict::TError`].
    pub t_error: u64,
    /// Largest `|t - t_oracle|` in world units over rays hitting the same triangle.
    pub max_t_error: f64,
    /// Largest error bound used along a ray (world units).
    pub max_bound: f64,
    /// The first faulty ray, both answers, for debugging.
    pub first_fault: Option<String>,
}

/// One line for people: the counts per verdict, the largest `t` error and
/// the largest bound (what `--verify` prints).
impl std::fmt::Display for OracleSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "oracle (binary64, requested positions): {} rays, {} agree, {} grazing, {} ties; {} faults ({} wrong triangle, {} missed, {} extra, {} t error); max t error {:.3e}, bound up to {:.3e}",
            self.rays, self.agree, self.grazing, self.ties, self.faults(), self.wrong_triangle, self.missed, self.extra, self.t_error, self.max_t_error, self.max_bound
        )
    }
}

impl OracleSummary {
    /// Rays that fail: wrong triangle, missed, extra or `t` error.
    pub fn faults(&self) -> u64 {
        self.wrong_triangle + self.missed + self.extra + self.t_error
    }
}

/// The oracle over some parts, ready to judge rays.
pub struct Oracle {
    tracer: ReferenceTracer,
    /// Per oracle triangle: the part and golden's primitive index.
    owner: Vec<(usize, u32)>,
    /// Hierarchy id to (part index, first oracle triangle).
    by_hier: BTreeMap<u8, (usize, u32)>,
    bounds: Vec<Bound>,
}

/// Why an oracle cannot be made.
#[derive(Clone, Debug, PartialEq)]
pub enum OracleError {
    /// A part's traced and source meshes differ in shape.
    Mismatched {
        /// The part's hierarchy id.
        hier: u8,
    },
    /// Two parts with one hierarchy id.
    DuplicateHier(u8),
}

impl fmt::Display for OracleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            OracleError::Mismatched { hier } => write!(
                f,
                "hierarchy {hier}: the traced mesh must have the source mesh's triangles and vertex count"
            ),
            OracleError::DuplicateHier(h) => write!(f, "hierarchy {h} appears twice"),
        }
    }
}

impl std::error::Error for OracleError {}

impl Oracle {
    /// The oracle over `parts`: every source triangle at `source + offset`, binary64.
    pub fn new(parts: &[Part]) -> Result<Oracle, OracleError> {
        let mut tris = Vec::new();
        let mut owner = Vec::new();
        let mut by_hier = BTreeMap::new();
        let mut bounds = Vec::with_capacity(parts.len());
        for (k, p) in parts.iter().enumerate() {
            if p.traced.triangles != p.source.triangles
                || p.traced.vertices.len() != p.source.vertices.len()
            {
                return Err(OracleError::Mismatched { hier: p.hier });
            }
            if by_hier.insert(p.hier, (k, tris.len() as u32)).is_some() {
                return Err(OracleError::DuplicateHier(p.hier));
            }
            let want: Vec<DVec3> = p
                .source
                .vertices
                .iter()
                .map(|v| v.as_dvec3() + p.offset)
                .collect();
            let mut b = Bound {
                shift: p.shift,
                local_magnitude: 0.0,
                world_magnitude: 0.0,
            };
            for (t, w) in p.traced.vertices.iter().zip(&want) {
                b.local_magnitude = b.local_magnitude.max(t.as_dvec3().abs().max_element());
                b.world_magnitude = b.world_magnitude.max(w.abs().max_element());
            }
            bounds.push(b);
            for (i, tri) in p.source.triangles.iter().enumerate() {
                tris.push(tri.map(|v| want[v as usize]));
                owner.push((k, i as u32));
            }
        }
        Ok(Oracle {
            tracer: ReferenceTracer::new(tris),
            owner,
            by_hier,
            bounds,
        })
    }

    /// Part `k`'s error bound for a ray from `org` (world units, across the ray).
    fn bound(&self, k: usize, org: DVec3) -> f64 {
        let b = &self.bounds[k];
        let local_org = (org - b.shift).abs().max_element();
        KERNEL_REL * (local_org + b.local_magnitude)
            + WORLD_REL * (org.abs().max_element() + b.world_magnitude)
    }

    /// The bound along a ray of direction `unit` (length 1) for oracle
    /// triangle `tri`: the bound across, over the cosine with its normal.
    fn along(&self, tri: u32, org: DVec3, unit: DVec3) -> f64 {
        let (k, _) = self.owner[tri as usize];
        let [a, b, c] = self.tracer.triangles()[tri as usize];
        let n = (b - a).cross(c - a);
        let len = n.length();
        let cos = if len > 0.0 && len.is_finite() {
            (n.dot(unit) / len).abs()
        } else {
            0.0
        };
        self.bound(k, org) / cos.max(MIN_COSINE)
    }

    /// Golden's hit as an oracle triangle index.
    fn index(&self, h: &Hit) -> Option<u32> {
        let &(_, first) = self.by_hier.get(&h.hier)?;
        Some(first + h.prim)
    }

    /// Judges golden's answer `got` for `ray`: the verdict, the `t` error
    /// (world units; 0 unless both hit one triangle) and the oracle's hit.
    pub fn judge(&self, ray: &Ray, got: Option<&Hit>) -> (Verdict, f64, Option<reference::RefHit>) {
        let want = self.tracer.closest(
            ray.origin.as_dvec3(),
            ray.dir.as_dvec3(),
            ray.tmin as f64,
            ray.tmax as f64,
        );
        let (v, err) = self.verdict(ray, got, want);
        (v, err, want)
    }

    fn verdict(
        &self,
        ray: &Ray,
        got: Option<&Hit>,
        want: Option<reference::RefHit>,
    ) -> (Verdict, f64) {
        let org = ray.origin.as_dvec3();
        let dir = ray.dir.as_dvec3();
        let len = dir.length();
        let unit = dir / len;
        let (tmin, tmax) = (ray.tmin as f64, ray.tmax as f64);
        let at = |t: f64| org + dir * t;
        // Near the ray's ends, a hit may fall on either side of them.
        let near_ends = |t: f64, d: f64| (t - tmin) * len <= d || (tmax - t) * len <= d;
        let got_tri = got.and_then(|h| self.index(h));
        match (got, got_tri, want) {
            (None, _, None) => (Verdict::Agree, 0.0),
            (Some(_), None, _) => (Verdict::Extra, 0.0),
            (Some(g), Some(a), Some(w)) if a == w.prim => {
                let d = self.along(a, org, unit);
                let err = (g.t as f64 - w.t).abs() * len;
                let v = if err <= d {
                    Verdict::Agree
                } else {
                    Verdict::TError
                };
                (v, err)
            }
            (Some(g), Some(a), Some(w)) => {
                let (da, db) = (self.along(a, org, unit), self.along(w.prim, org, unit));
                let tie = self
                    .tracer
                    .hits_prim(a, org, dir, 0.0)
                    .is_some_and(|ta| (ta - w.t).abs() * len <= da + db);
                if tie || (g.t as f64 - w.t).abs() * len <= da + db {
                    (Verdict::Tie, 0.0)
                } else if self.near_edge(w.prim, at(w.t), db)
                    || self.near_edge(a, at(g.t as f64), da)
                {
                    (Verdict::Grazing, 0.0)
                } else {
                    (Verdict::WrongTriangle, 0.0)
                }
            }
            (None, _, Some(w)) => {
                let d = self.along(w.prim, org, unit);
                if self.near_edge(w.prim, at(w.t), d) || near_ends(w.t, d) {
                    (Verdict::Grazing, 0.0)
                } else {
                    (Verdict::Missed, 0.0)
                }
            }
            (Some(g), Some(a), None) => {
                let d = self.along(a, org, unit);
                let t = g.t as f64;
                if self.near_edge(a, at(t), d) || near_ends(t, d) {
                    (Verdict::Grazing, 0.0)
                } else {
                    (Verdict::Extra, 0.0)
                }
            }
        }
    }

    /// True when `p` lies within `d` of an edge of oracle triangle `tri`.
    fn near_edge(&self, tri: u32, p: DVec3, d: f64) -> bool {
        let [a, b, c] = self.tracer.triangles()[tri as usize];
        [(a, b), (b, c), (c, a)]
            .iter()
            .any(|&(u, v)| segment_distance(p, u, v) <= d)
    }

    /// Judges every ray's answer, counting verdicts.
    pub fn judge_all<'h>(
        &self,
        rays: &[Ray],
        answers: impl IntoIterator<Item = Option<&'h Hit>>,
    ) -> OracleSummary {
        let mut s = OracleSummary::default();
        for (ray, got) in rays.iter().zip(answers) {
            self.count(&mut s, ray, got);
        }
        s
    }

    /// Judges one ray into `s`.
    pub fn count(&self, s: &mut OracleSummary, ray: &Ray, got: Option<&Hit>) {
        let (v, err, want) = self.judge(ray, got);
        s.rays += 1;
        let org = ray.origin.as_dvec3();
        s.oracle_hits += want.is_some() as u64;
        if let Some(w) = want {
            let unit = ray.dir.as_dvec3().normalize();
            s.max_bound = s.max_bound.max(self.along(w.prim, org, unit));
        }
        match v {
            Verdict::Agree => {
                s.agree += 1;
                s.max_t_error = s.max_t_error.max(err);
            }
            Verdict::Grazing => s.grazing += 1,
            Verdict::Tie => s.ties += 1,
            Verdict::WrongTriangle => s.wrong_triangle += 1,
            Verdict::Missed => s.missed += 1,
            Verdict::Extra => s.extra += 1,
            Verdict::TError => s.t_error += 1,
        }
        if v.is_fault() && s.first_fault.is_none() {
            let want = want.map(|w| {
                let (k, prim) = self.owner[w.prim as usize];
                let hier = self
                    .by_hier
                    .iter()
                    .find(|(_, &(p, _))| p == k)
                    .map(|(&h, _)| h);
                format!("hierarchy {hier:?} triangle {prim} at t = {}", w.t)
            });
            s.first_fault = Some(format!(
                "{v:?}: ray {ray:?}: golden {:?}, oracle {want:?}",
                got.map(|h| (h.hier, h.prim, h.t))
            ));
        }
    }
}

/// Distance from `p` to the segment `[a, b]`, binary64.
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let l2 = ab.length_squared();
    let s = if l2 > 0.0 {
        ((p - a).dot(ab) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p - (a + ab * s)).length()
}
