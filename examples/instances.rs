//! A renderer's scene: two meshes, one placed many times with transforms, ray masks, an
//! alpha-test filter, and hits that name the instance, the mesh and the triangle:
//! `cargo run --release --example instances`.

use glam::{Affine3A, Quat, Vec3, Vec3A};
use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, World, WorldHit};

/// The bits of `Instance::mask` this renderer uses.
const CAMERA: u32 = 0b01;
const SHADOW: u32 = 0b10;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut scene = World::builder();
    // A ground quad, placed once at the identity (no transform work when traced).
    let ground = scene.mesh(
        &[
            [-50.0, 0.0, -50.0],
            [50.0, 0.0, -50.0],
            [50.0, 0.0, 50.0],
            [-50.0, 0.0, 50.0],
        ],
        &[[0, 2, 1], [0, 3, 2]],
    )?;
    scene.instance(Instance::of(ground).mask(CAMERA | SHADOW));
    // A "tree": an octahedron of 8 triangles, planted 400 times, scaled and turned. The mesh
    // is stored once; each instance is a transform, a mask and the renderer's own id.
    let r = 1.0f32;
    let tree = scene.mesh(
        &[
            [r, 1.0, 0.0],
            [-r, 1.0, 0.0],
            [0.0, 1.0, r],
            [0.0, 1.0, -r],
            [0.0, 2.0, 0.0],
            [0.0, 0.0, 0.0],
        ],
        &[
            [0, 4, 2],
            [2, 4, 1],
            [1, 4, 3],
            [3, 4, 0],
            [0, 2, 5],
            [2, 1, 5],
            [1, 3, 5],
            [3, 0, 5],
        ],
    )?;
    for i in 0..400u32 {
        let (x, z) = ((i % 20) as f32 * 4.0 - 40.0, (i / 20) as f32 * 4.0 - 40.0);
        let place = Affine3A::from_scale_rotation_translation(
            Vec3::splat(1.0 + (i % 3) as f32 * 0.5),
            Quat::from_rotation_y(i as f32),
            Vec3::new(x, 0.0, z),
        );
        // Every fifth tree casts no shadow: shadow rays carry only the SHADOW bit.
        let mask = if i % 5 == 0 { CAMERA } else { CAMERA | SHADOW };
        scene.instance(Instance::of(tree).transform(place).mask(mask).id(i));
    }
    let world = scene.build(&BuildOptions::default())?;

    // A camera ray: the hit names the instance (and its id), the mesh and the triangle.
    let ray = Ray::new(Vec3A::new(-40.3, 1.2, -60.0), Vec3A::Z).with_mask(CAMERA);
    if let Some(hit) = world.closest_hit(&ray) {
        let normal = world.normal(&ray, &hit).unwrap_or(Vec3A::ZERO);
        println!(
            "instance {} (tree {}), mesh {}, triangle {}, t = {:.3}, normal {normal:.2}",
            hit.instance,
            world.instance(hit.instance).id,
            hit.geometry,
            hit.prim,
            hit.t
        );
    }

    // An alpha test: the upper half of every tree's triangles is "transparent" (u + v > 0.5
    // stands in for a texture lookup). A rejected candidate is skipped and the ray goes on.
    let alpha = |h: &WorldHit| h.geometry != tree.0 || h.u + h.v <= 0.5;
    let filtered = world.closest_hit_filtered(&ray, alpha);
    println!(
        "with the alpha test: {:?}",
        filtered.map(|h| (h.instance, h.t))
    );

    // Shadow rays from points on the ground towards a light: any hit, masked.
    let light = Vec3A::new(0.0, 60.0, 0.0);
    let shadow: Vec<Ray> = (0..64)
        .map(|k| {
            let p = Vec3A::new(
                (k % 8) as f32 * 10.0 - 35.0,
                0.0,
                (k / 8) as f32 * 10.0 - 35.0,
            );
            Ray::segment(p, light - p, 1e-4, 1.0).with_mask(SHADOW)
        })
        .collect();
    let mut occluded = vec![false; shadow.len()];
    // Coherent rays go through the instances as packets where that pays.
    world.any_hit_packet(&shadow, &mut occluded);
    let dark = occluded.iter().filter(|&&o| o).count();
    println!("{dark} of {} ground points in shadow", shadow.len());
    println!(
        "{} instances of {} meshes in {} bytes",
        world.instances().len(),
        world.geometries().len(),
        world.footprint().bytes
    );
    Ok(())
}
