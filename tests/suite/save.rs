//! Saved BVHs of a real scene: written to a file, read back, and held to the f64 oracle
//! (`quiver_lab::oracle`) as a freshly built BVH is in `equivalence.rs`, and to the BVH that
//! wrote them, bit for bit, in every layout.

use quiver_lab::oracle::Oracle;
use quiver_lab::rays;
use quiver_rt::traverse::reference;
use quiver_rt::{BuildOptions, Bvh, Layout, LoadError, RayQuery};
use quiver_scenes::Scene;
use rayon::prelude::*;

#[test]
fn a_loaded_scene_answers_as_the_oracle_and_as_the_saved_bvh() {
    let scene = Scene::load("tetra5").unwrap();
    let tris = scene.triangles();
    let oracle = Oracle::new(&tris);
    let mut all = rays::random_rays(&scene.bounds(), 3000, 7);
    all.extend(rays::camera_rays(&scene.camera, 48));
    let want = oracle.closest_hits(&all);
    let dir = std::env::temp_dir().join(format!("quiver-save-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for layout in Layout::ALL {
        let built = Bvh::build(&tris, &BuildOptions::default().layout(layout)).unwrap();
        let path = dir.join(format!("{layout}.qbvh"));
        let mut file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        built.save(&mut file).unwrap();
        drop(file);
        let loaded = Bvh::load(&mut std::fs::File::open(&path).unwrap())
            .unwrap_or_else(|e| panic!("{layout}: {e}"));
        let hits = all
            .par_iter()
            .zip(&want)
            .enumerate()
            .map(|(i, (ray, want))| {
                let got = loaded.closest_hit(ray);
                if let Err(e) = want.check(got) {
                    panic!("{layout}: ray {i} {ray:?}: {e}");
                }
                if !want.is_decidable() {
                    assert_eq!(got, reference::closest_hit(&tris, ray), "{layout}: ray {i}");
                }
                assert_eq!(got, built.closest_hit(ray), "{layout}: ray {i}");
                assert_eq!(loaded.any_hit(ray), got.is_some(), "{layout}: ray {i}");
                got.is_some() as usize
            })
            .sum::<usize>();
        assert!(hits > all.len() / 10, "{layout}: {hits} hits");
        let mut packets = vec![None; all.len()];
        loaded.closest_hit_packet(&all, &mut packets);
        for (i, (p, r)) in packets.iter().zip(&all).enumerate() {
            assert_eq!(*p, built.closest_hit(r), "{layout}: packet ray {i}");
        }
        // The file on disk, cut short, is an error naming the truncation.
        let bytes = std::fs::read(&path).unwrap();
        let cut = Bvh::from_bytes(&bytes[..bytes.len() / 2])
            .map(|_| ())
            .unwrap_err();
        assert!(
            matches!(cut, LoadError::Truncated { .. }),
            "{layout}: {cut}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
