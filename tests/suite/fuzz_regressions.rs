//! Replays every committed fuzz input — the seed corpora and any crash reproducers saved under
//! fuzz/artifacts — through the same checks the cargo-fuzz targets run (`quiver_lab::checks`).

use std::path::Path;

fn replay(target: &str, check: fn(&[u8])) -> usize {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let mut n = 0;
    for dir in [
        root.join("corpus").join(target),
        root.join("artifacts").join(target),
    ] {
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut files: Vec<_> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        for f in files {
            let data = std::fs::read(&f).unwrap();
            let r = std::panic::catch_unwind(|| check(&data));
            assert!(r.is_ok(), "{} fails", f.display());
            n += 1;
        }
    }
    n
}

#[test]
fn build_trace_inputs() {
    assert!(replay("build_trace", quiver_lab::checks::build_and_trace) >= 3);
}

#[test]
fn nff_inputs() {
    assert!(replay("nff", quiver_lab::checks::nff_round_trip) >= 3);
}

#[test]
fn obj_inputs() {
    assert!(replay("obj", quiver_lab::checks::obj_load) >= 2);
}

#[test]
fn packets_inputs() {
    assert!(replay("packets", quiver_lab::checks::packets_against_oracle) >= 3);
}

#[test]
fn render_inputs() {
    assert!(replay("render", quiver_lab::checks::render_nff) >= 3);
}

#[test]
fn lanes_inputs() {
    assert!(replay("lanes", quiver_lab::checks::analytic_lanes) >= 3);
}

#[test]
fn ply_inputs() {
    assert!(replay("ply", quiver_lab::checks::ply_load) >= 4);
}

#[test]
fn gltf_inputs() {
    assert!(replay("gltf", quiver_lab::checks::gltf_load) >= 3);
}

#[test]
fn instanced_inputs() {
    assert!(replay("instanced", quiver_lab::checks::instanced_against_oracle) >= 7);
}

#[test]
fn from_tree_inputs() {
    assert!(replay("from_tree", quiver_lab::checks::from_tree_against_reference) >= 3);
}

#[test]
fn point_queries_inputs() {
    assert!(replay("point_queries", quiver_lab::checks::point_queries) >= 3);
}

#[test]
fn saved_inputs() {
    assert!(replay("saved", quiver_lab::checks::saved_bvh) >= 3);
}
