//! The top level of a world: its per-instance leaf records ([`InstanceLeaf`]), each instance's world
//! box, and the 8-wide BVH over them.

use super::instance::motion_of;
use super::{Geometry, Instance, Motion};
use crate::builders::{build, BuildConfig, Builder};
use crate::geometry::{Aabb, PrimHit, Ray};
use crate::isa::Isa;
use crate::layout::ends::{node_ends, rows, Bvh8Ends};
use crate::layout::{bvh2::leaf_order, Bvh8, Inputs};
use crate::primitive::Primitive;
use glam::{Affine3A, Mat3A, Vec3A, Vec4, Vec4Swizzles};

/// The box of an object box's eight corners placed by `m` (empty for an empty box).
pub(super) fn corner_box(m: &Affine3A, b: &Aabb) -> Aabb {
    if b.is_empty() {
        return Aabb::EMPTY;
    }
    let mut out = Aabb::EMPTY;
    for k in 0..8 {
        let c = Vec3A::new(
            if k & 1 == 0 { b.min.x } else { b.max.x },
            if k & 2 == 0 { b.min.y } else { b.max.y },
            if k & 4 == 0 { b.min.z } else { b.max.z },
        );
        out.grow(m.transform_point3a(c));
    }
    out
}

/// A world box as the top level takes it: the walk meets the geometry through the inverse
/// transform, the box went through the forward one, so it is widened by 2^-20 of its
/// coordinates' size, and rounding in either cannot cull a hit the object-space walk would
/// find. In halves, and clamped to the finite range, so a box reaching toward f32::MAX stays
/// finite (an infinite box would drop the instance): every point the walk can meet is
/// finite, so the clamped box still holds it.
pub(super) fn padded(out: Aabb) -> Aabb {
    if out.is_empty() {
        return Aabb::EMPTY;
    }
    let half = out.min.abs().max(out.max.abs()) * 0.5 + (out.max * 0.5 - out.min * 0.5);
    let pad = half * (1.0 / (1u32 << 19) as f32);
    let finite = |v: Vec3A| v.clamp(Vec3A::splat(f32::MIN), Vec3A::splat(f32::MAX));
    Aabb::new(finite(out.min - pad), finite(out.max + pad))
}

/// Every instance's world box, in instance order: what the top level is built over. Kept
/// out of [`InstanceLeaf`], which the walks read, so a placed instance fills one cache line; the
/// refit computes them again from the instances ([`RefitInput::bounds`] of `edit::InstancesNow`).
///
/// [`RefitInput::bounds`]: crate::layout::refit::RefitInput::bounds
/// A removed instance (`removed[i]`, which may be shorter than `instances`) gets the empty
/// box, which the build leaves out, as it does any box that is not finite.
/// A moving instance's box holds it over its whole motion (`motions[i]`, which may be
/// shorter than `instances`).
pub(super) fn world_boxes<P: Primitive>(
    instances: &[Instance],
    motions: &[Option<Motion>],
    geometries: &[Geometry<P>],
    removed: &[bool],
) -> Vec<Aabb> {
    use rayon::prelude::*;
    instances
        .par_iter()
        .enumerate()
        .map(|(i, inst)| {
            let motion = motions.get(i).and_then(Option::as_ref);
            instance_box(inst, motion, geometries, removed.get(i) == Some(&true))
        })
        .collect()
}

/// The world box of instance `inst` as placed now, over its whole `motion` if it moves
/// (empty once removed).
pub(super) fn instance_box<P: Primitive>(
    inst: &Instance,
    motion: Option<&Motion>,
    geometries: &[Geometry<P>],
    removed: bool,
) -> Aabb {
    if removed {
        return Aabb::EMPTY;
    }
    let b = geometries[inst.geometry.0 as usize].bounds();
    match motion {
        Some(m) => m.world_box(&b),
        None => padded(corner_box(&inst.transform, &b)),
    }
}

/// The top level's boxes at both ends of the shutter, for a world with moving instances
/// (empty for one without): a moving instance's ends move with it ([`Motion::end_boxes`]),
/// a static one's are its box at both ends, a removed one's empty. A ray at time `t` then
/// enters each moving instance only near where it is at `t`, not anywhere along its path.
#[derive(Clone, Debug, Default)]
pub(super) struct TopEnds {
    /// One per node of the top level ([`Bvh8Ends`]): what a ray's walk meets.
    pub(super) nodes: Vec<Bvh8Ends>,
    /// One per top-level record (leaf order): its planes at time 0 and their change to
    /// time 1, the same floats as its slot in `nodes`; what a packet's rays meet a moving
    /// instance by before each goes in alone.
    pub(super) leaves: Vec<[[f32; 6]; 2]>,
}

impl TopEnds {
    /// The ends of `top`'s boxes, over the world's instances as they are now.
    pub(super) fn of<P: Primitive>(
        top: &Bvh8<InstanceLeaf>,
        instances: &[Instance],
        motions: &[Option<Motion>],
        geometries: &[Geometry<P>],
        removed: &[bool],
    ) -> TopEnds {
        if motions.is_empty() {
            return TopEnds::default();
        }
        let ends: Vec<[Aabb; 2]> = top
            .prims
            .iter()
            .map(|p| {
                let i = p.instance as usize;
                let inst = &instances[i];
                match (removed.get(i) == Some(&true), motion_of(motions, i)) {
                    (true, _) => [Aabb::EMPTY; 2],
                    (false, Some(m)) => m.end_boxes(&geometries[inst.geometry.0 as usize].bounds()),
                    (false, None) => [instance_box(inst, None, geometries, false); 2],
                }
            })
            .collect();
        let nodes = node_ends(&top.nodes, |prim| ends[prim]);
        let leaves = ends.iter().map(|&e| rows(e)).collect();
        TopEnds { nodes, leaves }
    }
}

/// The top-level BVH over `placed` (in instance order), whose world boxes are `boxes`:
/// 8-wide, one instance per leaf (an instance's test is a whole walk of its geometry, far
/// costlier than a node's). The build drops an instance whose box is not finite.
///
/// It keeps no input indices (`prim_ids` empty): the input index of a record is the
/// instance it names, so they would repeat `InstanceLeaf::instance` in 4 more bytes an instance.
/// Only a refit reads them, and `World::refit_top` lends it a copy for the while.
pub(super) fn top_level(placed: &[InstanceLeaf], boxes: &[Aabb], isa: Isa) -> Bvh8<InstanceLeaf> {
    let config = BuildConfig {
        max_leaf_size: 1,
        ..BuildConfig::default()
    };
    let tree =
        build(boxes, &config, Builder::Binned).expect("the top level's settings are in range");
    let inputs = Inputs::of(&tree, placed.len());
    let leaves = leaf_order(&tree, placed).into();
    let mut top = Bvh8::from_leaf_prims(&tree, leaves, inputs, isa, &config);
    debug_assert!(top
        .prims
        .iter()
        .map(|p| p.instance)
        .eq(top.prim_ids.iter().copied()));
    top.prim_ids = Vec::new();
    top
}

/// An instance as the walks read it, in top-level leaf order: one cache line, so a leaf's
/// instance costs the walk one miss. Its world box is not kept (the walks never read it:
/// the top level's nodes hold it); builds and refits compute it from the [`Instance`].
#[derive(Clone, Debug)]
#[repr(C, align(64))]
pub(crate) struct InstanceLeaf {
    /// World to object space, packed into 48 bytes: `to_object[j]` holds column `j` of the
    /// linear part in lanes 0..3 and the translation's component `j` in lane 3 (read through
    /// [`InstanceLeaf::world_to_object`], or lane by lane by the packet transform).
    pub(crate) to_object: [[f32; 4]; 3],
    pub(crate) geometry: u32,
    pub(crate) mask: u32,
    /// Its index among the instances.
    pub(crate) instance: u32,
    /// The identity transform: rays go in as they are.
    pub(crate) identity: bool,
    /// The instance moves: a ray goes in through its motion's transform at the ray's time
    /// (`to_object` is the one at time 0, for the point queries).
    pub(crate) moving: bool,
}

// One line per instance: a record that grew past it would cost every instance entry a
// second miss and the world's memory target (issue 26) its margin.
const _: () = assert!(std::mem::size_of::<InstanceLeaf>() == 64);

impl InstanceLeaf {
    /// Instance `index` (`inst`, with its checked `placement`), moving or not.
    pub(super) fn new(
        index: usize,
        inst: &Instance,
        (world_to_object, identity): (Affine3A, bool),
        moving: bool,
    ) -> InstanceLeaf {
        let (m, t) = (world_to_object.matrix3, world_to_object.translation);
        let col = |c: Vec3A, t: f32| [c.x, c.y, c.z, t];
        InstanceLeaf {
            to_object: [col(m.x_axis, t.x), col(m.y_axis, t.y), col(m.z_axis, t.z)],
            geometry: inst.geometry.0,
            mask: inst.mask,
            instance: index as u32,
            identity: identity && !moving,
            moving,
        }
    }

    /// World to object space: the inverse transform the instance was placed with, the same
    /// floats in the same lanes, so glam's products run as they did on it. Each vector is
    /// built from its three floats (lane 3 a copy of lane 2, as [`Vec3A::new`] makes it):
    /// lane 3 then repeats lane 2's arithmetic, and never multiplies a translation
    /// component, which may be subnormal (an assist per multiply, ~100x its cost) or make a
    /// subnormal product.
    #[inline(always)]
    pub(crate) fn world_to_object(&self) -> Affine3A {
        // Whole columns loaded and shuffled in registers (a load and a shuffle a column, two
        // shuffles for the translation); element by element, LLVM built each from scalars.
        let [x, y, z] = self.to_object.map(Vec4::from_array);
        let col = |c: Vec4| Vec3A::from_vec4(c.xyzz());
        Affine3A {
            matrix3: Mat3A::from_cols(col(x), col(y), col(z)),
            translation: Vec3A::new(x.w, y.w, z.w),
        }
    }

    /// `ray` in object space, searching up to `t_max` (the same parameter as in world space).
    #[inline(always)]
    pub(crate) fn local(&self, ray: &Ray, t_max: f32) -> Ray {
        if self.identity {
            return Ray { t_max, ..*ray };
        }
        into_object(&self.world_to_object(), ray, t_max)
    }
}

/// `ray` through the world-to-object transform `to_object`, searching up to `t_max` (the same
/// parameter in both spaces: the direction is transformed, not normalized).
#[inline(always)]
pub(crate) fn into_object(to_object: &Affine3A, ray: &Ray, t_max: f32) -> Ray {
    Ray {
        origin: to_object.transform_point3a(ray.origin),
        dir: to_object.transform_vector3a(ray.dir),
        t_max,
        ..*ray
    }
}

/// The top level's primitive, for the layout's sake only: [`Bvh8`] holds it as its leaf
/// data, which the world's walks read (they test the instance's geometry, never `intersect`).
///
/// `bounds` is not called either, so the record keeps no box. No path of `Bvh8<InstanceLeaf>`
/// reaches it: the build takes the world boxes from [`world_boxes`] (never `prim_bounds`),
/// `Bvh8::from_leaf_prims` lays out the tree's boxes (a plain leaf format packs no groups and
/// reads no primitive's box), `footprint` counts bytes, and the refit asks its source for
/// every leaf box ([`RefitInput::bounds`](crate::layout::refit::RefitInput::bounds), which
/// `edit::InstancesNow` computes from the instance); nor are the defaults that call it
/// (`surface_area`, `is_finite`), nor the layout's own queries. A path that did would be a bug,
/// so it panics rather than give a box.
impl Primitive for InstanceLeaf {
    fn bounds(&self) -> Aabb {
        unreachable!("a placed instance keeps no box: its world box comes from the instance")
    }
    fn intersect(&self, _: &Ray) -> Option<PrimHit> {
        None
    }
}
