//! [`Primitive`]: what a BVH can hold (bounds and a ray test), how the wide layouts store its
//! leaves ([`LeafFormat`]), and its packet hooks ([`PacketLeaf`], [`PacketLanes`]).

mod packet;

pub(crate) use packet::{lane, ray_rows, Lanes, PacketRays, CHUNKS, LANES};
pub use packet::{PacketLanes, PacketLeaf, PACKET_RAYS};

use crate::geometry::{Aabb, PrimHit, Ray, Triangle};
use crate::mask::bits;
use glam::Vec3A;

/// Anything a BVH can hold: it has bounds and a ray test. Triangles are the fast path; the
/// quiver-scenes crate adds the SPD's analytic shapes (spheres, cones, polygons, patches).
///
/// A new primitive type needs [`Primitive::bounds`] and [`Primitive::intersect`]; its packet
/// test then goes ray by ray unless it overrides [`Primitive::intersect_packet`].
///
/// # What the walks ask of `intersect`
///
/// - Return the *nearest* hit within the closed interval `[ray.t_min, ray.t_max]`, or `None`.
///   A hit exactly at `t_max` counts: return it.
/// - The walks call it with `t_max` lowered to the nearest hit found so far, so one primitive
///   is asked about several intervals of the same ray; the answer for a shorter interval must
///   be the longer interval's answer when that lies inside it (no state, no randomness).
/// - A returned hit is a *candidate*: the walk keeps the nearest one, and among hits at equal `t`
///   the one of the lowest primitive index (input order). A candidate at the current `t_max` from a
///   higher index is therefore offered and rejected. Every layout, the packet kernels and
///   [`reference`](crate::traverse::reference) apply the same rule, so all of them return the same
///   hit.
///
/// Two coincident squares, hit at the same distance: the lower index wins in every layout.
///
/// ```
/// use quiver_rt::traverse::reference;
/// use quiver_rt::{Aabb, BuildOptions, Bvh, Layout, PrimHit, Primitive, Ray, RayQuery};
/// use glam::Vec3A;
///
/// /// An axis-aligned unit square in the plane `z = z`.
/// #[derive(Clone)]
/// struct Square { z: f32 }
///
/// impl Primitive for Square {
///     fn bounds(&self) -> Aabb {
///         Aabb::new(Vec3A::new(0.0, 0.0, self.z), Vec3A::new(1.0, 1.0, self.z))
///     }
///     fn intersect(&self, r: &Ray) -> Option<PrimHit> {
///         let t = (self.z - r.origin.z) / r.dir.z;
///         let (x, y) = (r.origin.x + t * r.dir.x, r.origin.y + t * r.dir.y);
///         let inside = (0.0..=1.0).contains(&x) && (0.0..=1.0).contains(&y);
///         // Closed interval: a hit at exactly t_max is returned, and may tie.
///         (inside && r.t_min <= t && t <= r.t_max).then_some(PrimHit { t, u: x, v: y })
///     }
/// }
///
/// let squares = [Square { z: 1.0 }, Square { z: 0.0 }, Square { z: 0.0 }];
/// let ray = Ray::new(Vec3A::new(0.5, 0.5, -1.0), Vec3A::Z);
/// for layout in Layout::ALL {
///     let bvh = Bvh::build(&squares, &BuildOptions::default().layout(layout)).unwrap();
///     let hit = bvh.closest_hit(&ray).unwrap();
///     assert_eq!((hit.prim, hit.t), (1, 1.0)); // 1 and 2 tie at t = 1: the lower index
///     assert_eq!(Some(hit), reference::closest_hit(&squares, &ray));
/// }
/// ```
///
/// A primitive placed in a scene by its own bounds and test:
///
/// ```
/// use quiver_rt::{Aabb, Bvh, PrimHit, Primitive, Ray, RayQuery};
/// use glam::Vec3A;
///
/// /// A point-like target: a tiny axis-aligned cube.
/// #[derive(Clone)]
/// struct Cube(Vec3A);
///
/// impl Primitive for Cube {
///     fn bounds(&self) -> Aabb {
///         Aabb::new(self.0 - 0.5, self.0 + 0.5)
///     }
///     fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
///         // Slab test against the cube's own box.
///         let b = self.bounds();
///         let (t0, t1) = ((b.min - ray.origin) / ray.dir, (b.max - ray.origin) / ray.dir);
///         let (near, far) = (t0.min(t1).max_element(), t0.max(t1).min_element());
///         let t = near.max(ray.t_min);
///         (t <= far && t <= ray.t_max).then_some(PrimHit { t, u: 0.0, v: 0.0 })
///     }
/// }
///
/// let cubes: Vec<Cube> = (0..10).map(|i| Cube(Vec3A::new(3.0 * i as f32, 0.0, 0.0))).collect();
/// let bvh = Bvh::new(&cubes);
/// let hit = bvh.closest_hit(&Ray::new(Vec3A::new(6.0, 0.0, -5.0), Vec3A::Z)).unwrap();
/// assert_eq!((hit.prim, hit.t), (2, 4.5));
/// ```
pub trait Primitive: Clone + Send + Sync {
    /// How quiver tests this type: as itself ([`LeafFormat::Plain`], the default: through
    /// [`Primitive::intersect`]), or as a triangle.
    ///
    /// A triangle format makes quiver test each primitive as the triangle [`Primitive::triangle`]
    /// returns, with [`Triangle::intersect`]'s arithmetic ([`LeafFormat::FastTriangles`]) or
    /// [`crate::intersect::Watertight`]'s ([`LeafFormat::WatertightTriangles`]), in every layout
    /// (the wide ones store it in SIMD groups of four), every packet kernel and
    /// [`reference`](crate::traverse::reference); `intersect` is then never called by quiver. A
    /// type that must decide hits itself (an alpha-tested triangle, say) keeps `Plain` and does so
    /// in `intersect`.
    ///
    /// ```
    /// use quiver_rt::primitive::LeafFormat;
    /// use quiver_rt::traverse::reference;
    /// use quiver_rt::{Aabb, Bvh, PrimHit, Primitive, Ray, RayQuery, Triangle};
    /// use glam::Vec3A;
    ///
    /// /// A triangle carrying a material: tested as its triangle.
    /// #[derive(Clone)]
    /// struct Painted { tri: Triangle, material: u16 }
    ///
    /// impl Primitive for Painted {
    ///     const LEAF_FORMAT: LeafFormat = LeafFormat::FastTriangles;
    ///     fn triangle(&self) -> Option<Triangle> {
    ///         Some(self.tri)
    ///     }
    ///     fn bounds(&self) -> Aabb {
    ///         self.tri.bounds()
    ///     }
    ///     fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
    ///         self.tri.intersect(ray) // for callers of our own; quiver tests `triangle()`
    ///     }
    /// }
    ///
    /// let tri = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let prims = [Painted { tri, material: 3 }];
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 1.0), -Vec3A::Z);
    /// let hit = Bvh::new(&prims).closest_hit(&ray).unwrap();
    /// assert_eq!(Some(hit), reference::closest_hit(&[tri], &ray));
    /// assert_eq!(prims[hit.prim as usize].material, 3);
    /// ```
    const LEAF_FORMAT: LeafFormat = LeafFormat::Plain;

    /// The triangle quiver tests for a type with a triangle [`Primitive::LEAF_FORMAT`] (its
    /// [`Primitive::bounds`] must contain it); `None` there makes the primitive one no ray
    /// hits. Not read for [`LeafFormat::Plain`].
    #[inline]
    fn triangle(&self) -> Option<Triangle> {
        None
    }

    /// Bounding box. A primitive with a non-finite coordinate must return a box with a NaN
    /// (see [`Aabb::is_finite`]) so the builders drop it.
    fn bounds(&self) -> Aabb;
    /// The nearest hit within `[ray.t_min, ray.t_max]` (both ends included), if any: distance
    /// and two surface parameters (barycentrics for triangles). See "What the walks ask of
    /// `intersect`" above: answers are candidates, ties go to the lower primitive index.
    /// Not called for a type with a triangle [`Primitive::LEAF_FORMAT`].
    fn intersect(&self, ray: &Ray) -> Option<PrimHit>;
    /// Surface area, which the build cost models other than the SAH weigh
    /// ([`crate::builders::CostModel`]): the measure of the lines that meet the primitive, so a
    /// flat primitive counts both sides. The default is the bounding box's half surface area
    /// (a flat primitive across its box's largest face); [`Triangle`] gives its own.
    ///
    /// ```
    /// use quiver_rt::{Primitive, Triangle};
    /// use glam::Vec3A;
    /// let t = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// assert_eq!(t.surface_area(), 1.0); // both sides of a triangle of area 1/2
    /// ```
    fn surface_area(&self) -> f32 {
        self.bounds().half_area()
    }
    /// The geometric normal at `at` (the hit point, in the primitive's own space), where the
    /// ray's `hit` was found: any length, on the side the primitive faces. The default is the
    /// face normal of [`Primitive::triangle`] (`(v1 - v0) × (v2 - v0)`), and `None` for a type
    /// without one.
    ///
    /// ```
    /// use quiver_rt::{PrimHit, Primitive, Triangle};
    /// use glam::Vec3A;
    /// let t = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let h = PrimHit { t: 1.0, u: 0.2, v: 0.2 };
    /// assert_eq!(t.geometric_normal(Vec3A::new(0.2, 0.2, 0.0), &h), Some(Vec3A::Z));
    /// ```
    fn geometric_normal(&self, at: Vec3A, hit: &PrimHit) -> Option<Vec3A> {
        let _ = (at, hit);
        let t = self.triangle()?;
        Some((t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]))
    }
    /// True when every coordinate is finite; others are invisible (builds drop them).
    fn is_finite(&self) -> bool {
        self.bounds().is_finite()
    }
    /// This primitive with every coordinate and length multiplied by `s`, a power of two
    /// (exact in f32). Its tests must commute with the scaling: a ray scaled alike hits it at
    /// `s` times the distance with the same surface parameters.
    ///
    /// A [`crate::Bvh`] over a scene far from unit size (extent outside `2^-20..=2^20`)
    /// builds and traces it scaled to unit size, where no product of lengths overflows or
    /// underflows f32; `None` (the default) keeps such a scene at its own size.
    ///
    /// ```
    /// use quiver_rt::{Primitive, Ray, Triangle};
    /// use glam::Vec3A;
    /// let t = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y);
    /// let ray = Ray::new(Vec3A::new(0.25, 0.25, 1.0), -Vec3A::Z);
    /// let small = t.scaled(0.5).unwrap();
    /// let half = Ray::new(ray.origin * 0.5, ray.dir);
    /// assert_eq!(small.intersect(&half).unwrap().t, 0.5 * t.intersect(&ray).unwrap().t);
    /// ```
    #[inline]
    fn scaled(&self, s: f32) -> Option<Self> {
        let _ = s;
        None
    }
    /// The packet kernels' test of a leaf of these primitives against the rays of a packet
    /// that enter it: for every ray of [`PacketLeaf::rays`] (within its current interval,
    /// [`PacketLeaf::ray`]) and primitive `j` of `leaf` it hits, call
    /// [`PacketLeaf::report`]. Each ray's hits must be exactly what
    /// [`Primitive::intersect`] finds for it.
    ///
    /// Called for [`LeafFormat::Plain`] types only (triangle formats are tested as SIMD
    /// groups). The default goes ray by ray; a type of its own can test eight rays at a time
    /// ([`PacketLeaf::lanes`]).
    #[inline(always)]
    fn intersect_packet<F>(leaf: &[Self], rays: &mut PacketLeaf<'_, F>)
    where
        Self: Sized,
        F: FnMut(usize, u32, PrimHit) -> Option<f32>,
    {
        for i in bits(rays.rays()) {
            let mut ray = rays.ray(i);
            for (j, p) in leaf.iter().enumerate() {
                if let Some(h) = p.intersect(&ray) {
                    rays.report(i, j, h);
                    if rays.rays() >> i & 1 == 0 {
                        break;
                    }
                    ray = rays.ray(i);
                }
            }
        }
    }
}

/// How quiver tests a primitive type and how the wide layouts store its leaves: see
/// [`Primitive::LEAF_FORMAT`]. A triangle format is tested as the type's
/// [`Primitive::triangle`] everywhere, with that format's arithmetic, and
/// [`Primitive::intersect`] is not consulted; `Plain` is tested through `intersect`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LeafFormat {
    /// The primitives themselves, tested one by one.
    Plain,
    /// Four triangles per group in SoA with precomputed edges and normal, tested at once with
    /// the arithmetic of [`Triangle::intersect`].
    FastTriangles,
    /// Four triangles per group in SoA (their vertices), tested at once with the arithmetic
    /// of [`crate::intersect::Watertight`], falling back to it for a lane on an edge.
    WatertightTriangles,
}

impl Primitive for Triangle {
    const LEAF_FORMAT: LeafFormat = LeafFormat::FastTriangles;

    #[inline]
    fn triangle(&self) -> Option<Triangle> {
        Some(*self)
    }

    #[inline]
    fn bounds(&self) -> Aabb {
        if self.is_finite() {
            Triangle::bounds(self)
        } else {
            Aabb::new(Vec3A::NAN, Vec3A::NAN)
        }
    }

    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> Option<PrimHit> {
        Triangle::intersect(self, ray)
    }

    #[inline]
    fn is_finite(&self) -> bool {
        Triangle::is_finite(self)
    }

    #[inline]
    fn scaled(&self, s: f32) -> Option<Self> {
        Some(Triangle {
            v: self.v.map(|p| p * s),
        })
    }

    #[inline]
    fn surface_area(&self) -> f32 {
        (self.v[1] - self.v[0])
            .cross(self.v[2] - self.v[0])
            .length()
    }
}
