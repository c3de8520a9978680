//! Where a default build's time goes, phase by phase, on any scene `quiver` can load:
//! `cargo run --release -p quiver-scenes --example build_phases -- meshes/dragon_vrip.ply.gz`.
//! Prints the median of 5 runs of each phase at 1 and 2 threads: primitive bounds, the binary
//! tree, the layout (`Bvh::from_tree`: tree check, collapse, nodes, leaf groups, primitive
//! copy) and the whole build (`BuildOptions::build` with that builder, so `Bvh::new` for the
//! default) for comparison, and a refit of that build to the same triangles (`Bvh::refit`).
//! `BUILDER=lbvh` (any builder name) picks the builder, `REPS` the number of runs.

use quiver_rt::builders::{build, prim_bounds, BuildConfig, Builder};
use quiver_rt::{BuildOptions, Bvh};
use std::time::Instant;

fn ms<R>(f: impl FnOnce() -> R) -> (R, f64) {
    let t = Instant::now();
    let r = f();
    (r, t.elapsed().as_secs_f64() * 1e3)
}

/// A fingerprint of the tree (every node's box bits and links, the leaf order), to see that
/// a change to the builder left the tree as it was and that thread counts agree.
fn fingerprint(tree: &quiver_rt::builders::BuildTree) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for n in &tree.nodes {
        for v in n
            .bounds
            .min
            .to_array()
            .iter()
            .chain(&n.bounds.max.to_array())
        {
            v.to_bits().hash(&mut h);
        }
        format!("{:?}", n.kind).hash(&mut h);
    }
    tree.prim_indices.hash(&mut h);
    h.finish()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let spec = std::env::args().nth(1).unwrap_or_else(|| "tetra9".into());
    let scene = quiver_scenes::Scene::load(&spec).unwrap_or_else(|e| panic!("{spec}: {e}"));
    let tris = scene.triangles();
    println!("{spec}: {} triangles", tris.len());
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let options = BuildOptions::default().thread_pool(&pool);
        // The default build counts leaves in the default layout's groups.
        let config = BuildConfig {
            leaf_group: quiver_rt::Layout::default().leaf_group(),
            ..BuildConfig::default()
        };
        let builder: Builder =
            std::env::var("BUILDER").map_or(Builder::Binned, |b| b.parse().unwrap());
        let tree = pool.install(|| build(&prim_bounds(&tris), &config, builder));
        println!(
            "threads {threads}: tree {:016x}, SAH {:.3}, {:?}",
            fingerprint(&tree),
            tree.sah_cost(&config),
            tree.stats()
        );
        let bvh8 = pool.install(|| {
            quiver_rt::Bvh8::from_tree(&tree, &tris, &config, quiver_rt::Isa::detect()).unwrap()
        });
        let mut h = std::collections::hash_map::DefaultHasher::new();
        std::hash::Hash::hash(bvh8.node_bytes(), &mut h);
        std::hash::Hash::hash(quiver_rt::bytemuck::cast_slice::<_, u8>(bvh8.groups()), &mut h);
        println!(
            "threads {threads}: bvh8 {:016x}",
            std::hash::Hasher::finish(&h)
        );
        let (mut b, mut t, mut l, mut all, mut r) = (vec![], vec![], vec![], vec![], vec![]);
        let reps: usize = std::env::var("REPS").map_or(5, |r| r.parse().unwrap());
        for _ in 0..reps {
            pool.install(|| {
                let (bounds, mb) = ms(|| prim_bounds(&tris));
                let (tree, mt) = ms(|| build(&bounds, &config, builder));
                let (bvh, ml) = ms(|| Bvh::from_tree(&tree, &tris, &options).unwrap());
                drop(bvh);
                let (mut bvh, ma) = ms(|| options.clone().builder(builder).build(&tris));
                let (refit, mr) = ms(|| bvh.refit(&tris));
                refit.unwrap();
                drop(bvh);
                r.push(mr);
                b.push(mb);
                t.push(mt);
                l.push(ml);
                all.push(ma);
            });
        }
        println!(
            "threads {threads}: bounds {:.1} ms, tree {:.1} ms, layout {:.1} ms, build {:.1} ms, refit {:.1} ms",
            median(b),
            median(t),
            median(l),
            median(all),
            median(r)
        );
    }
}
