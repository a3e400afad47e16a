//! Toggle bits unreachable by design that a netlist proof cannot see,
//! because they hold by what the streams carry rather than by the logic
//! (SPEC 10.5). The streams and buffers of one LOD `L` (`LEVEL_NETS`)
//! carry node records of LOD `L`, or a record of 0 (an `End` or reference
//! beat, an unwritten word; docs/hardware.md, the upper builder's `base{d}`
//! and `level{d}` beats). A record is a valid node (SPEC 3:
//! the fetchers refuse any other, 8.13), so at LOD `L` its coordinates are
//! below `2^L` and its `lod` field is `L`. In a level-`L` beat the
//! coordinate bits from `L` up, and the `lod` bits that are 0 in `L`, never
//! change. Like Yosys's constants these are computed on every report, from
//! the layout golden defines, and a bit named here that the regression
//! toggled is a contradiction that fails the report.

use golden::layout::{Field, NodeLayout};
use golden::Params;

/// The nets that carry one LOD's records, by module prefix: `{L}` is the
/// LOD. The record sits at bit 0 of each: the builder's `base{d}` and
/// `level{d}` beats, a grouping unit's output (`u_group{d}` groups level
/// `d + 1` into LOD `d`), the writer's body words (`count` above the
/// record's low bits), the merger's leaf FIFO words of LOD `d`.
const LEVEL_NETS: [(&str, &[&str]); 3] = [
    (
        "upper_builder_",
        &[
            "base{L}_data",
            "base{L}_skid_data",
            "base{L}_skid_data_rec",
            "base{L}_skid_spare_data",
            "level{L}_beat",
            "level{L}_data",
            "level{L}_skid_data",
            "level{L}_skid_spare_data",
            "u_group{L}_out_data",
            "u_group{L}_rec",
        ],
    ),
    (
        "record_writer_",
        &["level{L}_data", "u_level{L}_nbody", "u_level{L}_rbody"],
    ),
    (
        "hierarchy_merger_",
        &["u_builder_level{L}_data", "leaves{L}_rec"],
    ),
];

/// Morton codes of one LOD's records (coordinates interleaved, `x` lowest,
/// by `merge::network::morton_code`), by module prefix as [`LEVEL_NETS`].
const MORTON_NETS: [(&str, &[&str]); 1] = [(
    "upper_builder_",
    &["base{L}_skid_data_rec_x_morton", "u_group{L}_rec_x_morton"],
)];

/// One table's nets: the module's prefix, and the net patterns.
type Nets = [(&'static str, &'static [&'static str])];

/// The reason the toggle point `what` (`net[bit]`) of `module` cannot
/// toggle, when a rule names it.
pub fn reason(module: &str, what: &str) -> Option<String> {
    let (net, bit) = what.split_once('[')?;
    let bit: u32 = bit.strip_suffix(']')?.parse().ok()?;
    // `record_writer_level_*` serves every level in one module.
    if module.starts_with("record_writer_level") {
        return None;
    }
    let level_in = |table: &Nets| level_net(table, module, net);
    if let Some((p, level)) = level_in(&MORTON_NETS) {
        return (bit >= 3 * level && bit < 3 * p.coord_bits()).then(|| {
            format!("Morton bit {bit} of a LOD-{level} record: its coordinates lie below 2^{level}, so its bits from {} up are 0 (by design, cosim::coverage::by_design)", 3 * level)
        });
    }
    let (p, level) = level_in(&LEVEL_NETS)?;
    record_bit(&p, level, bit)
}

/// The nets whose whole word is the builder's level beat
/// (`BuilderLayout::level`: `rec`, `ref`, `kind`, `index`, `records`,
/// `err`), by module prefix as [`LEVEL_NETS`]; the other level nets carry
/// the record at bit 0 and other words above it.
const LEVEL_BEAT_NETS: [(&str, &[&str]); 3] = [
    (
        "upper_builder_",
        &[
            "level{L}_beat",
            "level{L}_data",
            "level{L}_skid_data",
            "level{L}_skid_spare_data",
        ],
    ),
    ("record_writer_", &["level{L}_data"]),
    ("hierarchy_merger_", &["u_builder_level{L}_data"]),
];

/// The field of golden's layouts that toggle point `what` (`net[bit]`) of
/// `module` is, when the net carries one LOD's records (`LEVEL_NETS`):
/// `rec.count[11]`, `index[5]`. The report prints it beside the point, so
/// that a bit is read as the field it is.
pub fn field_of(module: &str, what: &str) -> Option<String> {
    let (net, bit) = what.split_once('[')?;
    let bit: u32 = bit.strip_suffix(']')?.parse().ok()?;
    let (p, _) = level_net(&LEVEL_NETS, module, net)?;
    if let Some(f) = field_at(NodeLayout::new(&p).layout(), bit, "rec.") {
        return Some(f);
    }
    level_net(&LEVEL_BEAT_NETS, module, net)?;
    let bl = golden::merge::upper_builder::unit::BuilderLayout::new(&p);
    match bit.checked_sub(bl.refer.offset) {
        Some(k) if k < bl.refer.width => field_at(&golden::layout::RefLayout::new(&p), k, "ref."),
        _ => field_at(&bl.level, bit, ""),
    }
}

/// The parameters and the LOD of `net` of `module` when `table` names it
/// (the net's LOD within the module's `D`).
fn level_net(table: &Nets, module: &str, net: &str) -> Option<(Params, u32)> {
    let (prefix, nets) = table
        .iter()
        .find(|(prefix, _)| module.starts_with(prefix))?;
    let p = params_of(&module[prefix.len()..])?;
    let level = nets.iter().find_map(|n| level_of(n, net))?;
    (level <= p.max_lod as u32).then_some((p, level))
}

/// The field of `layout` holding bit `bit`, as `{prefix}{name}[k]`.
fn field_at(layout: &golden::layout::Layout, bit: u32, prefix: &str) -> Option<String> {
    layout.fields().find_map(|f| {
        (f.offset..f.offset + f.width)
            .contains(&bit)
            .then(|| format!("{prefix}{}[{}]", f.name, bit - f.offset))
    })
}

/// Why bit `bit` of a record of LOD `level` never changes, if it does not.
fn record_bit(p: &Params, level: u32, bit: u32) -> Option<String> {
    let nl = NodeLayout::new(p);
    let k = |f: &Field| {
        (f.offset..f.offset + f.width)
            .contains(&bit)
            .then(|| bit - f.offset)
    };
    if let Some(k) = k(nl.lod()) {
        return ((level >> k) & 1 == 0).then(|| {
            format!("`lod` bit {k} of a level-{level} beat: 0 in {level} and in an `End` beat's 0 (by design, cosim::coverage::by_design)")
        });
    }
    let (axis, k) = [("x", nl.x()), ("y", nl.y()), ("z", nl.z())]
        .into_iter()
        .find_map(|(a, f)| k(f).map(|k| (a, k)))?;
    (k >= level).then(|| {
        format!("`{axis}` bit {k} of a level-{level} beat: a node of LOD {level} lies below 2^{level} (by design, cosim::coverage::by_design)")
    })
}

/// The level `L` of `net` when it is `pattern` with `{L}` replaced.
fn level_of(pattern: &str, net: &str) -> Option<u32> {
    let (head, tail) = pattern.split_once("{L}")?;
    let digits = net.strip_prefix(head)?.strip_suffix(tail)?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// The parameters of a module named `..._d{D}_q{Q}_i{I}_h{H}...` after its
/// prefix ([`Params::tag`]).
fn params_of(rest: &str) -> Option<Params> {
    let mut parts = rest.split('_');
    let mut next = |c: char| -> Option<u8> { parts.next()?.strip_prefix(c)?.parse().ok() };
    let (d, q, i, h) = (next('d')?, next('q')?, next('i')?, next('h')?);
    Params::new(d, q, i, h).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At D = 8 the record is `leaf` (bit 0), `lod` (bits 1..=4), `x`
    /// (5..=12), `y`, `z`: the rule names the coordinate bits from `L` up
    /// and the `lod` bits 0 in `L`, nothing else, and only on level nets.
    #[test]
    fn names_coordinates_above_the_level_and_lod_bits_zero_in_it() {
        let ub = "upper_builder_d8_q0_i12_h3";
        // Level 3 = 0b0011: lod bits 2 and 3 (nets bits 3, 4) never change.
        assert!(reason(ub, "level3_data[1]").is_none());
        assert!(reason(ub, "level3_data[3]")
            .unwrap()
            .contains("`lod` bit 2"));
        assert!(reason(ub, "level3_data[4]").is_some());
        // x bits 0..=2 reachable at level 3, 3..=7 not.
        assert!(reason(ub, "level3_data[7]").is_none());
        assert!(reason(ub, "level3_data[8]").unwrap().contains("`x` bit 3"));
        assert!(reason(ub, "level3_skid_spare_data[12]").is_some());
        assert!(reason(ub, "level3_beat[20]").unwrap().contains("`y` bit 7"));
        assert!(reason(ub, "level3_beat[21]").is_none());
        assert!(reason(ub, "level3_beat[28]").unwrap().contains("`z` bit 7"));
        // `first` and beyond: not the rule's.
        assert!(reason(ub, "level0_data[29]").is_none());
        // Level 8 = D: every coordinate bit is reachable.
        assert!(reason(ub, "level8_data[12]").is_none());
        assert!(reason(ub, "level9_data[12]").is_none());
        assert!(reason(ub, "base3_data[12]").is_some());
        assert!(reason(ub, "l3_nodes[12]").is_none());
        assert!(reason("record_writer_d8_q0_i12_h3_c5", "level0_data[5]").is_some());
        assert!(reason("record_writer_d8_q0_i12_h3_c5", "u_level2_rbody[27]").is_some());
        assert!(reason(ub, "u_group7_rec[11]").is_none());
        assert!(reason(ub, "u_group7_rec[12]").is_some());
        assert!(reason(ub, "u_group6_rec[12]").is_some());
        assert!(reason("record_writer_level_d8_q0_i12_h3_c5", "level_data[5]").is_none());
        let top = "hierarchy_merger_d8_q0_i12_h3_k2_ov1_2_r16_f256_c5_l6";
        assert!(reason(top, "u_builder_level2_data[27]").is_some());
        assert!(reason(top, "leaves5_rec[12]").is_some());
        // Morton codes (24 bits at D = 8): from 3L up.
        assert!(reason(ub, "u_group2_rec_x_morton[5]").is_none());
        assert!(reason(ub, "u_group2_rec_x_morton[6]")
            .unwrap()
            .contains("Morton bit 6"));
        assert!(reason(ub, "base0_skid_data_rec_x_morton[0]").is_some());
        assert!(reason(ub, "base8_skid_data_rec_x_morton[23]").is_none());
        assert!(reason(top, "u_builder_level2_data").is_none());
    }

    /// At D = 8, I = 12, H = 3 the level beat is `rec` (bits 0..=52:
    /// `leaf`, `lod`, `x`, `y`, `z`, `first` from 29, `count` from 41),
    /// `ref` (53..=67: `node`, then `hier`), `kind`, `index` (70..=81),
    /// `records`, `err` (94).
    #[test]
    fn names_the_field_of_a_level_net_bit() {
        let ub = "upper_builder_d8_q0_i12_h3";
        assert_eq!(
            field_of(ub, "level3_data[0]").as_deref(),
            Some("rec.leaf[0]")
        );
        assert_eq!(
            field_of(ub, "level3_data[40]").as_deref(),
            Some("rec.first[11]")
        );
        assert_eq!(
            field_of(ub, "level3_beat[41]").as_deref(),
            Some("rec.count[0]")
        );
        assert_eq!(
            field_of(ub, "level3_data[53]").as_deref(),
            Some("ref.node[0]")
        );
        assert_eq!(
            field_of(ub, "level3_data[67]").as_deref(),
            Some("ref.hier[2]")
        );
        assert_eq!(field_of(ub, "level3_data[75]").as_deref(), Some("index[5]"));
        assert_eq!(field_of(ub, "level3_data[94]").as_deref(), Some("err[0]"));
        let top = "hierarchy_merger_d8_q0_i12_h3_k2_ov1_2_r16_f256_c5_l6";
        assert_eq!(
            field_of(top, "u_builder_level0_data[82]").as_deref(),
            Some("records[0]")
        );
        // A record's bits on a net that carries other words above it.
        assert_eq!(
            field_of(ub, "base2_data[30]").as_deref(),
            Some("rec.first[1]")
        );
        assert_eq!(field_of(ub, "base2_data[60]"), None);
        assert_eq!(field_of(ub, "l3_nodes[2]"), None);
        assert_eq!(
            field_of("record_writer_level_d8_q0_i12_h3_c5", "level_data[5]"),
            None
        );
    }
}
