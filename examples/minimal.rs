//! From a vertex buffer and an index buffer to a hit: `cargo run --example minimal`.

use glam::Vec3A;
use quiver_rt::{Bvh, Ray, RayQuery};

fn main() -> Result<(), quiver_rt::MeshError> {
    // A unit square in the z = 0 plane: four vertices, two triangles.
    let positions = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    let indices = [[0, 1, 2], [0, 2, 3]];
    let bvh = Bvh::from_mesh(&positions, &indices)?;

    let ray = Ray::new(Vec3A::new(0.25, 0.75, 2.0), Vec3A::new(0.0, 0.0, -1.0));
    match bvh.closest_hit(&ray) {
        Some(hit) => println!(
            "triangle {} at t = {} (u {}, v {})",
            hit.prim, hit.t, hit.u, hit.v
        ),
        None => println!("miss"),
    }
    // AVX2 where the CPU has it, else the portable kernels: the same answers either way.
    println!("kernels: {}", bvh.isa());
    Ok(())
}
