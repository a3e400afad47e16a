//! Subsets (issue 19 item 6, paragraph 67): `scenes/groups.json` merges the
//! bunny and the teapot into one hierarchy and the floor and the pillar into
//! another, traced together. Run golden-only through the library (what
//! `hiermerge run --no-rtl --verify` does), every frame has one merged
//! hierarchy per group, the static group's merge is done once, and the
//! merged hits agree with the separate hierarchies and with the binary64
//! oracle over the triangles where the scene puts them (SPEC 6.10).

use std::path::PathBuf;

use golden::scene::Scene;
use hiermerge::run::{preflight, run, Options};

#[test]
fn each_group_is_one_merged_hierarchy_and_hits_agree_with_the_oracle() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/groups.json");
    let file = path.display().to_string();
    let mut scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    preflight::check(&scene, &file).unwrap_or_else(|e| panic!("{e}"));
    // Fewer pixels than the file asks for: the test needs the merges and
    // the compared rays, not the picture.
    (scene.width, scene.height) = (64, 48);
    let dir = tempfile::tempdir().unwrap();
    let options = Options {
        verify: true,
        ..Options::golden_only(dir.path())
    };
    let report = run(&scene, &options).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(report.mismatches, 0);
    assert!(scene.groups.len() >= 2, "the scene names several groups");
    let top = scene.params.hier_capacity() - 1;
    let mut static_merges = 0;
    for f in &report.frames {
        assert_eq!(f.groups.len(), scene.groups.len(), "frame {}", f.frame);
        let mut roots: Vec<u8> = Vec::new();
        for (g, (out, ids)) in f.groups.iter().zip(&scene.groups).enumerate() {
            let names: Vec<&str> = ids
                .iter()
                .map(|&i| scene.objects[i as usize].name.as_str())
                .collect();
            assert_eq!(out.objects, names, "frame {} group {g}", f.frame);
            // Each group of two or more objects is one merged hierarchy,
            // its own id below 2^H.
            assert_eq!(out.root, Some((top - g as u64) as u8), "frame {}", f.frame);
            assert!(out.merged_nodes > 0, "frame {} group {g}", f.frame);
            roots.push(out.root.unwrap());
            let all_static = ids
                .iter()
                .all(|&i| scene.objects[i as usize].motion == golden::frames::Motion::Static);
            if all_static && out.merged {
                static_merges += 1;
            }
        }
        roots.dedup();
        assert_eq!(roots.len(), scene.groups.len(), "distinct roots");
        let c = f.comparison.as_ref().expect("primary rays are compared");
        assert_eq!(c.hit_mismatches, 0, "frame {}", f.frame);
        let o = c.oracle.as_ref().expect("--verify judges the hits");
        assert_eq!(o.faults(), 0, "frame {}: {o}", f.frame);
        assert!(
            o.agree * 4 > o.rays && o.oracle_hits > 0,
            "frame {}: {o}",
            f.frame
        );
    }
    assert_eq!(static_merges, 1, "the static group is merged once");
}
