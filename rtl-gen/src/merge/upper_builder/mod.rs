//! S616 in hardware, every level at once (SPEC.md section 8.11): the upper
//! builder. A chain of stages, one per LOD `d = D` down to 0; stage `d`'s
//! level is the 2-way Morton merge of the grouping of level `d + 1` (an
//! [`upper_level_unit`] instance) with the base nodes at LOD `d` (stream
//! `base{d}`), inner (grouped) first at a voxel, exactly `build_levels`'s
//! `merge_level`. Every level streams concurrently, one beat per clock per
//! stage, and leaves on its own stream `level{d}` as it flows up to the
//! next grouping. The top rule of SPEC 4.7 / 8.6 is decided when a level's
//! `End` passes, from the level's counts and whether any base node lies
//! above it; the levels above the top are grouped but not sent.
//!
//! Why the top can be decided in-flight: a level of a single node with no
//! base above it has a single grouped node at every shallower LOD, and that
//! node is completed only by the level's `End`; so when stage `d` decides
//! that `d` is the top, no beat of a shallower level has left yet.

use golden::merge::merge_level::unit::base_kind;
use golden::merge::upper_builder::level_unit::UpperLayout;
use golden::merge::upper_builder::unit::{level_out_kind, BuilderLayout};
use golden::params::Params;

use super::morton_code;
use crate::{Module, Signal, Stream};

mod level;
pub use level::{upper_level_name, upper_level_unit};

/// Module name of the upper builder for `p`.
pub fn upper_builder_name(p: &Params) -> String {
    format!("upper_builder_{}", p.tag())
}

/// The head of one level's stream: the beat stage `d` would pass now.
#[derive(Clone, Copy)]
struct Head<'m> {
    valid: Signal<'m>,
    end: Signal<'m>,
    rec: Signal<'m>,
    refer: Signal<'m>,
    /// A [`level_out_kind`] code (`END` only with `end`).
    kind: Signal<'m>,
    /// The grouping's error flag of a grouped node.
    gerr: Signal<'m>,
    /// Passing the head takes the grouped stream's head.
    from_g: Signal<'m>,
    /// Passing the head takes the base stream's head.
    from_b: Signal<'m>,
}

/// The fields of a `base{d}` beat: record, reference, `End`, the out kind.
struct BaseFields<'m> {
    rec: Signal<'m>,
    refer: Signal<'m>,
    end: Signal<'m>,
    kind: Signal<'m>,
}

fn base_fields<'m>(m: &'m Module, bl: &BuilderLayout, data: Signal<'m>) -> BaseFields<'m> {
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let kind = data.view(&bl.base.kind);
    let end = kind.eq(lit(base_kind::END, 2));
    let created = kind.eq(lit(base_kind::CREATED, 2));
    BaseFields {
        rec: data.view(&bl.base.rec),
        refer: data.view(&bl.base.refer),
        end,
        kind: m.first_of(
            &[
                (end, lit(level_out_kind::END, 2)),
                (created, lit(level_out_kind::CREATED, 2)),
            ],
            lit(level_out_kind::REUSED, 2),
        ),
    }
}

/// `a * b`, unsigned, `width` bits wide (enough for the product): shift
/// and add, one adder per bit of `b`.
fn multiply<'m>(m: &'m Module, a: Signal<'m>, b: Signal<'m>, width: u32) -> Signal<'m> {
    let a = a.zext(width);
    let mut acc = m.lit(0, width);
    for i in 0..b.width().min(width) {
        let shifted = if i == 0 {
            a
        } else {
            m.concat(&[a.slice(width - 1 - i, 0), m.lit(0, i)])
        };
        acc = acc.add(b.bit(i).mux(shifted, m.lit(0, width)), width);
    }
    acc
}

/// SPEC 4.7's exception test on a LOD-0 record: its box covers more than
/// half the scene, `(hx-lx+1)(hy-ly+1)(hz-lz+1) * 2 > 2^(3Q)`, exactly.
fn covers_most_of_scene<'m>(
    m: &'m Module,
    bl: &BuilderLayout,
    rec: Signal<'m>,
    q: u32,
) -> Signal<'m> {
    if q == 0 {
        // One cell per axis: 1 * 2 > 1.
        return m.lit(1, 1);
    }
    let extent = |a: usize| {
        let lo = rec.view(bl.node.lo(a));
        let hi = rec.view(bl.node.hi(a));
        hi.sub(lo, q).zext(q + 1).add(1, q + 1)
    };
    let w = 3 * q + 3;
    let xy = multiply(m, extent(0), extent(1), w);
    let cells = multiply(m, xy, extent(2), w).name("root_cells");
    // cells * 2 > 2^(3Q)  <=>  cells > 2^(3Q - 1).
    cells.gt(m.lit(1u128 << (3 * q - 1), w))
}

/// The upper builder for `p`: input streams `base0` .. `base{D}`
/// ([`BuilderLayout::base`] beats), output streams `level0` .. `level{D}`
/// and `done` ([`BuilderLayout`]).
pub fn upper_builder_unit(p: &Params) -> Module {
    let m = Module::new(&upper_builder_name(p));
    let bl = BuilderLayout::new(p);
    let ul = UpperLayout::new(p);
    let nl = &bl.node;
    let dmax = p.max_lod as usize;
    let i = p.index_bits as u32;
    let lb = p.lod_bits();
    let lit = |v: u64, w: u32| m.lit(v as u128, w);
    let zero = lit(0, 1);
    let one = lit(1, 1);

    // The merge's end: the `done` beat handed to its skid buffer clears
    // every per-merge register.
    let done_ready = m.wire("done_in_ready", 1);
    let top_found = m.reg("top_found", 1);
    let top_lod = m.reg("top_lod", lb);
    let done_err = m.reg("done_err", 1);
    let root_suppressed = m.reg("root_suppressed", 1);

    let bases: Vec<Stream> = (0..=dmax)
        .map(|d| {
            Stream::input(&m, &format!("base{d}"), bl.base.width())
                .skid_buffer(&format!("base{d}_skid"))
        })
        .collect();
    let base_f: Vec<BaseFields> = bases.iter().map(|b| base_fields(&m, &bl, b.data)).collect();
    let grouping = upper_level_unit(p);
    // groups[d] groups level d + 1 into LOD d.
    let groups: Vec<_> = (0..dmax)
        .map(|d| m.instance(&format!("u_group{d}"), &grouping))
        .collect();

    // The heads of every level.
    let heads: Vec<Head> = (0..=dmax)
        .map(|d| {
            let b = &base_f[d];
            if d == dmax {
                return Head {
                    valid: bases[d].valid,
                    end: b.end,
                    rec: b.rec,
                    refer: b.refer,
                    kind: b.kind,
                    gerr: zero,
                    from_g: zero,
                    from_b: one,
                };
            }
            let g = groups[d];
            let g_valid = g.output("out_valid");
            let g_data = g.output("out_data");
            let g_rec = g_data.view(&ul.rec);
            let g_end = g_data.view(&ul.end);
            let g_err = g_data.view(&ul.err);
            let g_first = morton_code(&m, g_rec.coords(nl)).le(morton_code(&m, b.rec.coords(nl)));
            let both_end = (g_end & b.end).name(&format!("l{d}_end"));
            let take_g = (!g_end & (b.end | g_first)).name(&format!("l{d}_take_group"));
            Head {
                valid: (g_valid & bases[d].valid).name(&format!("l{d}_valid")),
                end: both_end,
                rec: take_g.mux(g_rec, b.rec),
                refer: take_g.mux(lit(0, b.refer.width()), b.refer),
                kind: take_g.mux(lit(level_out_kind::GROUPED, 2), b.kind),
                gerr: take_g & g_err,
                from_g: take_g | both_end,
                from_b: !take_g,
            }
        })
        .collect();

    // Per stage: whether its base stream has (had) a node this merge, and
    // whether that is known yet (its head shown, or a node taken).
    let had_base: Vec<Signal> = (0..dmax)
        .map(|d| m.reg(&format!("l{d}_had_base"), 1))
        .collect();
    let mut known_below = vec![one];
    let mut base_below = vec![zero];
    for d in 0..dmax {
        let known = had_base[d] | bases[d].valid;
        let here = had_base[d] | (bases[d].valid & !base_f[d].end);
        known_below.push((known_below[d] & known).name(&format!("l{}_above_known", d + 1)));
        base_below.push((base_below[d] | here).name(&format!("l{}_base_above", d + 1)));
    }

    let done_valid = m.reg("done_valid", 1);
    let clear = (done_valid & done_ready).name("merge_clear");
    let has_leaf: Vec<Signal> = (0..=dmax)
        .map(|d| m.reg(&format!("l{d}_has_leaf"), 1))
        .collect();
    let mut decide_top = zero;
    let mut decided_lod = top_lod;
    let mut root_cut = zero;
    let mut stage0_end = zero;
    let mut stage0_err = zero;
    for d in (0..=dmax).rev() {
        let h = heads[d];
        let done = m.reg(&format!("l{d}_done"), 1);
        let n = m.reg(&format!("l{d}_nodes"), i);
        let ovf = m.reg(&format!("l{d}_nodes_ovf"), 1);
        let r = m.reg(&format!("l{d}_records"), i);
        let up_ready = if d > 0 {
            groups[d - 1].output("in_ready")
        } else {
            one
        };
        let out_ready = m.wire(&format!("level{d}_in_ready"), 1);
        // An End waits until every base stream above is known to be empty
        // or not: the top rule needs it for a level of one node. An empty
        // level (`d >= 1`) is never the top, so its End passes at once:
        // the empty levels below the merging level drain during the merge
        // pass instead of after the first base node at the merging level.
        let empty = if d > 0 { n.eq(lit(0, i)) & !ovf } else { zero };
        let end_ok = (!h.end | known_below[d] | empty).name(&format!("l{d}_end_ok"));
        let leaf = h.rec.view(nl.leaf());
        // The half-scene rule: a grouped LOD-0 node alone in its level.
        let suppress_root = if d == 0 {
            let covers = covers_most_of_scene(&m, &bl, h.rec, p.quant_bits as u32);
            (h.from_g & !h.end & base_f[0].end & covers & !has_leaf[1]).name("root_suppress")
        } else {
            zero
        };
        let emit = h.end.mux(
            !top_found & !(if d == 0 { root_suppressed } else { zero }),
            !top_found & !suppress_root,
        );
        let ready_all = (h.valid & !done & end_ok).name(&format!("l{d}_ready_all"));
        let fire = (ready_all & up_ready & (!emit | out_ready)).name(&format!("l{d}_fire"));
        let node_fire = fire & !h.end;
        let end_fire = (fire & h.end).name(&format!("l{d}_end_fire"));

        if d > 0 {
            let g = groups[d - 1];
            g.connect("in_valid", ready_all & (!emit | out_ready));
            let child = h.rec.slice(nl.first().offset - 1, 1);
            g.connect("in_data", m.concat(&[h.end, child]));
        }
        if d < dmax {
            groups[d].connect("out_ready", fire & h.from_g);
        }
        bases[d].ready.drive(fire & h.from_b);

        // The level's out beat.
        let index_next = n.add(1, i + 1).name(&format!("l{d}_index_next"));
        let rec_out = h.end.mux(lit(0, h.rec.width()), h.rec);
        let ref_out = h.end.mux(lit(0, h.refer.width()), h.refer);
        let data = m.concat(&[h.gerr | ovf, r, n, h.kind, ref_out, rec_out]);
        debug_assert_eq!(data.width(), bl.level.width());
        Stream {
            valid: (ready_all & up_ready & emit).name(&format!("level{d}_in_valid")),
            ready: out_ready,
            data: data.name(&format!("level{d}_beat")),
        }
        .skid_buffer(&format!("level{d}_skid"))
        .output(&format!("level{d}"));

        // Per-merge state.
        done.next(clear.mux(zero, done | end_fire));
        n.next(clear.mux(lit(0, i), node_fire.mux(index_next.slice(i - 1, 0), n)));
        ovf.next(clear.mux(zero, ovf | (node_fire & index_next.bit(i))));
        let is_record =
            (!h.kind.eq(lit(level_out_kind::REUSED, 2))).name(&format!("l{d}_is_record"));
        r.next(clear.mux(lit(0, i), (node_fire & is_record).mux(r.add(1, i), r)));
        if d < dmax {
            had_base[d].next(clear.mux(zero, had_base[d] | (node_fire & h.from_b)));
        }
        let reused_leaf = h.kind.eq(lit(level_out_kind::REUSED, 2)) & leaf;
        has_leaf[d].next(clear.mux(zero, has_leaf[d] | (node_fire & reused_leaf)));

        // The top rule at this level's End.
        if d > 0 {
            let single = n.eq(lit(1, i)) & !ovf & !base_below[d] & !has_leaf[d];
            let top_here = (end_fire & !top_found & single).name(&format!("l{d}_is_top"));
            decided_lod = top_here.mux(lit(d as u64, lb), decided_lod);
            decide_top = decide_top | top_here;
        } else {
            root_cut = node_fire & suppress_root;
            stage0_end = end_fire & !top_found;
            // No top: an empty base, or a reused leaf at the LOD-0 top.
            let empty = n.eq(lit(0, i)) & !ovf;
            stage0_err = !root_suppressed & (empty | has_leaf[0]);
            decided_lod = stage0_end.mux(root_suppressed.mux(lit(1, lb), lit(0, lb)), decided_lod);
            decide_top = decide_top | stage0_end;
            // Every stage has passed its End when stage 0 has.
            done_valid.next(clear.mux(zero, done_valid | end_fire));
        }
    }
    top_found.next(clear.mux(zero, top_found | decide_top));
    top_lod.next(clear.mux(lit(0, lb), decided_lod));
    done_err.next(clear.mux(zero, done_err | (stage0_end & stage0_err)));
    root_suppressed.next(clear.mux(zero, root_suppressed | root_cut));

    // `done` leaves through a skid buffer the clock after stage 0's End.
    let done_beat = m.concat(&[done_err, top_lod]);
    debug_assert_eq!(done_beat.width(), bl.done.width());
    Stream {
        valid: done_valid,
        ready: done_ready,
        data: done_beat,
    }
    .skid_buffer("done_skid")
    .output("done");
    m
}
