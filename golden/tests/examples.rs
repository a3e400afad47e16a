//! Every example of `golden/examples/` runs (what `cargo run -p golden
//! --example NAME` does, without its `main`), and says what it should: so
//! that CI keeps the examples a third party starts from working.

#[allow(dead_code)]
#[path = "../examples/build_hierarchy.rs"]
mod build_hierarchy;
#[allow(dead_code)]
#[path = "../examples/place_and_merge.rs"]
mod place_and_merge;
#[allow(dead_code)]
#[path = "../examples/save_and_load.rs"]
mod save_and_load;
#[allow(dead_code)]
#[path = "../examples/trace_rays.rs"]
mod trace_rays;

fn has(out: &str, line_start: &str) {
    assert!(
        out.lines().any(|l| l.starts_with(line_start)),
        "no line starting {line_start:?} in:\n{out}"
    );
}

#[test]
fn build_hierarchy_builds_and_checks() {
    let out = build_hierarchy::run(None).unwrap();
    has(&out, "9152 triangles, parameters d16_q8_i24_h4");
    has(&out, "checker: ok");
    has(&out, "rebuilt 3 times in a kept context");
    // A mesh file, as a user passes one.
    let bunny = golden::scenes::shared_mesh_path("bunny.obj");
    let out = build_hierarchy::run(Some(bunny.to_str().unwrap())).unwrap();
    has(&out, "3674 triangles");
}

#[test]
fn place_and_merge_traces_the_merge_like_its_inputs() {
    let out = place_and_merge::run().unwrap();
    has(&out, "moving object 2 by one voxel");
    assert!(out.contains("Retranslated, Retranslated"), "{out}");
    has(&out, "merged at level Some(");
    has(&out, "5000 rays");
}

#[test]
fn trace_rays_reads_the_counts() {
    let out = trace_rays::run().unwrap();
    has(&out, "4096 primary rays");
    // "N shadow rays: M shadowed": the hills shadow some hits, not all.
    let line = out.lines().find(|l| l.contains(" shadow rays: ")).unwrap();
    let num = |i: usize| -> u32 { line.split([' ', ':']).nth(i).unwrap().parse().unwrap() };
    let (rays, shadowed) = (num(0), num(4));
    assert!(shadowed > 0 && shadowed < rays, "{line}");
}

#[test]
fn save_and_load_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("t.hmh");
    let out = save_and_load::run(&file).unwrap();
    has(&out, "loaded: identical to the built hierarchy");
    assert!(file.exists());
}
