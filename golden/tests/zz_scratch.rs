use golden::merge::merger_unit::MergerSizes;
use golden::vectors::hard_merges::hard_merges;
use golden::vectors::merge::MergeDesign;
use golden::Params;
#[test]
fn scratch() {
    let p = Params::new(8, 0, 12, 3).unwrap();
    for mode in [
        golden::merge::MergeMode::Overlap { num: 1, den: 2 },
        golden::merge::MergeMode::PerNode { num: 1, den: 2 },
    ] {
        let d = MergeDesign {
            params: p,
            inputs: 2,
            mode,
            ..MergeDesign::default()
        };
        let mut sizes = MergerSizes::new(&p);
        sizes.leaf_bits = 6;
        sizes.capacity_bits = 5;
        let h = hard_merges(&d, sizes).unwrap();
        println!("{} merges, overflowing {}", h.merges.len(), h.overflowing);
        for tx in &h.merges {
            let roots: Vec<u64> = tx.cfg.inputs.iter().map(|i| i.root_count as u64).collect();
            let mut per = std::collections::BTreeSet::new();
            for l in &tx.leaves {
                per.insert(l.record.voxel.lod);
            }
            println!(
                "roots {roots:?} chosen {:?} leaves lods {per:?} werr {}",
                tx.chosen, tx.writer.header.err
            );
        }
    }
}
