//! Node records and references pack and unpack bit-exactly at the extreme
//! parameter sets, and a value too wide for its field is an error.

use golden::bits::Bits;
use golden::layout::{LayoutError, NodeLayout, RefLayout};
use golden::store::{NodeRecord, Reference};
use golden::{Params, VoxelAddr};
use proptest::prelude::*;

fn extremes() -> [Params; 3] {
    [
        Params::new(31, 16, 32, 8).unwrap(),
        Params::new(1, 0, 1, 1).unwrap(),
        Params::new(16, 8, 24, 4).unwrap(),
    ]
}

/// A record with every field at a value that fits `p`'s widths (taken from
/// the raw random words by masking, so all-ones is reachable).
fn record_from(p: &Params, raw: [u64; 12]) -> NodeRecord {
    let mask = |bits: u32, v: u64| {
        if bits >= 64 {
            v
        } else {
            v & ((1u64 << bits) - 1)
        }
    };
    let q = p.quant_bits as u32;
    let d = p.max_lod as u32;
    let i = p.index_bits as u32;
    NodeRecord {
        leaf: raw[0] & 1 == 1,
        voxel: VoxelAddr::new(
            mask(p.lod_bits(), raw[1]) as u8,
            mask(d, raw[2]) as u32,
            mask(d, raw[3]) as u32,
            mask(d, raw[4]) as u32,
        ),
        lo: [
            mask(q, raw[5]) as u16,
            mask(q, raw[6]) as u16,
            mask(q, raw[7]) as u16,
        ],
        hi: [
            mask(q, raw[8]) as u16,
            mask(q, raw[9]) as u16,
            mask(q, raw[10]) as u16,
        ],
        first: mask(i, raw[11]) as u32,
        count: mask(i, raw[11].rotate_left(32)) as u32,
    }
}

/// The record's bits assembled independently of `Bits`: a bool per bit, in
/// the SPEC's field order and widths.
fn reference_bits(p: &Params, n: &NodeRecord) -> Vec<bool> {
    let (d, q, i) = (p.max_lod as u32, p.quant_bits as u32, p.index_bits as u32);
    let fields: Vec<(u64, u32)> = vec![
        (n.leaf as u64, 1),
        (n.voxel.lod as u64, p.lod_bits()),
        (n.voxel.x as u64, d),
        (n.voxel.y as u64, d),
        (n.voxel.z as u64, d),
        (n.lo[0] as u64, q),
        (n.lo[1] as u64, q),
        (n.lo[2] as u64, q),
        (n.hi[0] as u64, q),
        (n.hi[1] as u64, q),
        (n.hi[2] as u64, q),
        (n.first as u64, i),
        (n.count as u64, i),
    ];
    fields
        .into_iter()
        .flat_map(|(v, w)| (0..w).map(move |b| (v >> b) & 1 == 1))
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn node_records_round_trip(which in 0usize..3, raw in any::<[u64; 12]>()) {
        let p = extremes()[which];
        let l = NodeLayout::new(&p);
        let n = record_from(&p, raw);
        let bits = n.pack(&l).unwrap();
        prop_assert_eq!(bits.width(), l.width());
        let expect = reference_bits(&p, &n);
        prop_assert_eq!(expect.len() as u32, l.width());
        for (k, &b) in expect.iter().enumerate() {
            prop_assert_eq!(bits.bit(k as u32), b, "bit {}", k);
        }
        prop_assert_eq!(NodeRecord::unpack(&bits, &l).unwrap(), n);
        // Via words, as a file or a simulator would hand them back.
        let again = Bits::from_words(bits.words(), l.width()).unwrap();
        prop_assert_eq!(NodeRecord::unpack(&again, &l).unwrap(), n);
    }

    #[test]
    fn references_round_trip(which in 0usize..3, node in any::<u32>(), hier in any::<u8>()) {
        let p = extremes()[which];
        let l = RefLayout::new(&p);
        let r = Reference {
            node: if p.index_bits == 32 { node } else { node & ((1 << p.index_bits) - 1) },
            hier: hier & ((1u16 << p.hier_bits) - 1) as u8,
        };
        let bits = r.pack(&l).unwrap();
        prop_assert_eq!(bits.width(), p.index_bits as u32 + p.hier_bits as u32);
        for k in 0..p.index_bits as u32 {
            prop_assert_eq!(bits.bit(k), (r.node >> k) & 1 == 1);
        }
        for k in 0..p.hier_bits as u32 {
            prop_assert_eq!(bits.bit(p.index_bits as u32 + k), (r.hier >> k) & 1 == 1);
        }
        prop_assert_eq!(Reference::unpack(&bits, &l).unwrap(), r);
    }
}

#[test]
fn values_too_wide_are_errors_naming_the_field() {
    let p = Params::new(1, 0, 1, 1).unwrap();
    let l = NodeLayout::new(&p);
    let ok = NodeRecord {
        leaf: true,
        voxel: VoxelAddr::new(1, 1, 0, 1),
        lo: [0; 3],
        hi: [0; 3],
        first: 1,
        count: 1,
    };
    assert!(ok.pack(&l).is_ok());
    let cases: [(&str, NodeRecord); 5] = [
        (
            "lod",
            NodeRecord {
                voxel: VoxelAddr::new(2, 0, 0, 0),
                ..ok
            },
        ),
        (
            "y",
            NodeRecord {
                voxel: VoxelAddr::new(1, 0, 2, 0),
                ..ok
            },
        ),
        (
            "hi_z",
            NodeRecord {
                hi: [0, 0, 1],
                ..ok
            },
        ),
        ("first", NodeRecord { first: 2, ..ok }),
        ("count", NodeRecord { count: 2, ..ok }),
    ];
    for (field, n) in cases {
        match n.pack(&l) {
            Err(LayoutError::DoesNotFit { field: f, .. }) => assert_eq!(f, field),
            other => panic!("{field}: expected DoesNotFit, got {other:?}"),
        }
    }
    let rl = RefLayout::new(&p);
    assert!(matches!(
        Reference { hier: 2, node: 0 }.pack(&rl),
        Err(LayoutError::DoesNotFit {
            field: "hier",
            value: 2,
            width: 1
        })
    ));
    // A record of another layout's width is refused, not misread.
    let wide = NodeLayout::new(&Params::new(2, 0, 1, 1).unwrap());
    assert!(matches!(
        NodeRecord::unpack(&wide.zero(), &l),
        Err(LayoutError::WrongWidth { .. })
    ));
}

#[test]
fn packed_record_of_a_real_build_round_trips() {
    let p = Params::new(10, 5, 20, 3).unwrap();
    let tris = [[
        glam::DVec3::new(1.0, 2.0, 3.0),
        glam::DVec3::new(900.0, 2.5, 3.0),
        glam::DVec3::new(4.0, 700.0, 1000.0),
    ]];
    let h = golden::build::build_grid_triangles(&tris, &p, 3).unwrap();
    let l = NodeLayout::new(&p);
    for (bits, n) in h.pack_nodes().unwrap().iter().zip(&h.nodes) {
        assert_eq!(&NodeRecord::unpack(bits, &l).unwrap(), n);
    }
    let rl = RefLayout::new(&p);
    for (bits, r) in h.pack_refs().unwrap().iter().zip(&h.refs) {
        assert_eq!(&Reference::unpack(bits, &rl).unwrap(), r);
    }
}
