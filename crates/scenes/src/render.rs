//! A Whitted ray tracer that follows the SPD testing procedure (Haines, Readme.txt of the
//! SPD): eye rays at pixel corners, depth limit 5 with the eye ray at depth 1, reflection rays
//! from every hit on a reflective surface, Snell refraction through every transmitter (a
//! reflection ray on total internal reflection), one shadow ray per light the surface faces,
//! Phong highlights on reflective surfaces, an ambient term.
//!
//! It simulates only what the scene calls for: a scene without reflective materials spawns no
//! secondary rays, one without transmitters no refraction rays, and a light behind a surface
//! costs no shadow ray. Shadow rays use the any-hit query.
//!
//! ```
//! use quiver_rt::BuildOptions;
//! use quiver_scenes::render::{render, RenderConfig};
//! use quiver_scenes::{accel::SceneBvh, Scene};
//! let scene = Scene::load("tetra3").unwrap();
//! let bvh = SceneBvh::build(&scene, &BuildOptions::default()).unwrap();
//! let out = render(&scene, &bvh, &RenderConfig { res: 16, ..Default::default() }, &|_| {});
//! assert_eq!(out.rays.eye, 17 * 17);
//! assert_eq!(out.rays.refract, 0); // tetra has no transmitters
//! ```

use crate::accel::SceneBvh;
use crate::scene::{Material, Scene};
use glam::Vec3A;
use quiver_rt::geometry::{offset_ray_origin, unit_or_zero, Hit, Ray};
use quiver_rt::traverse::{
    ConservativeBoxes, Counters, NoFilter, NoStats, PacketMode, PacketQuery, RayQuery, Stats,
    PACKET_RAYS,
};
use rayon::prelude::*;
use std::ops::{AddAssign, Range};

/// Render settings.
#[derive(Clone, Debug)]
pub struct RenderConfig {
    /// Image width and height in pixels; `(res + 1)^2` eye rays are traced.
    pub res: u32,
    /// Deepest ray generation traced (the eye ray is depth 1).
    pub max_depth: u32,
    /// Objects whose material index is listed here are two-sided: their normal is turned to
    /// face the incoming ray (the SPD asks this of the teapot).
    pub two_sided: Vec<u32>,
    /// Count traversal work (nodes, leaves, tests) and nodes visited per eye ray.
    pub counters: bool,
    /// How secondary rays leave the surface.
    pub offset: Offset,
    /// Trace eye rays in packets of 8 x 8 pixel corners, and each light's shadow rays from
    /// those corners as a packet (see [`quiver_rt::traverse::PacketMode::Auto`]); secondary rays
    /// go one by one. The image and the ray counts are the same either way; only the
    /// traversal work counted with [`RenderConfig::counters`] differs.
    pub packets: bool,
    /// Keep the pixels ([`Rendered::rgb`]); without it only their digest
    /// ([`Rendered::image_digest`]) is kept, for a second pass that checks it drew the same
    /// image without holding a second one (3 bytes a pixel: 805 MB at 16384²).
    pub keep_image: bool,
    /// With [`RenderConfig::counters`], keep the nodes each eye ray visited
    /// ([`Rendered::eye_nodes`], 4 bytes a corner; with several time samples, the last
    /// sample's).
    pub eye_nodes: bool,
    /// Times in the shutter each corner's eye ray is traced at, its colours averaged: motion
    /// blur, for a scene that moves (see [`crate::instanced::Instanced::build_moving`]). 1,
    /// the default, traces each eye ray once at time 0, as the SPD does; `s > 1` traces it
    /// `s` times, sample `k` at a time jittered within `[k / s, (k + 1) / s)` (the jitter
    /// fixed by corner and sample, so a render repeats exactly), every secondary ray at its
    /// eye ray's time. The ray counts are then those of `s` renders.
    pub time_samples: u32,
}

impl RenderConfig {
    /// The most memory a render holds at once beyond the scene and its BVH, in bytes, on
    /// `threads` worker threads: the image (with [`RenderConfig::keep_image`]), the nodes per
    /// eye ray (with [`RenderConfig::counters`] and [`RenderConfig::eye_nodes`]), the first and
    /// last corner row of every band of 8 (the pixels between two bands need both), and per
    /// thread one band's corner colours and eye-ray buffers. The first three are their
    /// allocations' exact sizes, the per-thread buffers an upper bound (1 KB per corner of a
    /// packet group); for callers to refuse a resolution before it cannot fit.
    ///
    /// ```
    /// use quiver_scenes::render::RenderConfig;
    /// let c = RenderConfig { res: 16384, ..RenderConfig::default() };
    /// // 805 MB of pixels and 1.07 GB of band edges dominate.
    /// assert!((1_800_000_000..2_000_000_000).contains(&c.memory_bytes(2)));
    /// ```
    pub fn memory_bytes(&self, threads: usize) -> u64 {
        let res = self.res as u64;
        let n = res + 1;
        let bands = n.div_ceil(TILE as u64);
        let image = if self.keep_image { 3 * res * res } else { 0 };
        let nodes = if self.counters && self.eye_nodes {
            4 * n * n
        } else {
            0
        };
        let edges = bands * 2 * n * std::mem::size_of::<Vec3A>() as u64;
        let digests = 8 * res + bands * std::mem::size_of::<RayCounts>() as u64 * 2;
        // A band's corner colours (twice with time samples: their sum), its across/down
        // parts, a pixel row, and a packet group's scratch (rays, hits, surfaces for 16 tiles
        // of 64 corners: well under 1 KB each).
        let colours = if self.time_samples > 1 { 2 } else { 1 };
        let band = colours * TILE as u64 * n * std::mem::size_of::<Vec3A>() as u64
            + (n + TILE as u64) * 16
            + 3 * res
            + (TILE * TILE * GROUP) as u64 * 1024;
        image + nodes + edges + digests + threads.max(1) as u64 * band
    }
}

/// How a secondary ray avoids re-hitting the surface it starts on. Both measure their
/// distances against the scene's size (its largest extent), so a scene renders alike at any
/// scale.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Offset {
    /// Start at the hit point and ignore hits closer than `1e-4 * (size / 10 + max|p|)`: the
    /// classical tracers' epsilon behind the SPD's published counts (about 1e-4 at the SPD
    /// scenes' sizes of 1 to 100), and the default. It skips real geometry closer than that
    /// (balls: the contacts of touching spheres).
    #[default]
    Epsilon,
    /// Move the origin a few ulps off the surface along the normal (Wächter & Binder): finds
    /// geometry however close. Its near-origin threshold is taken relative to the scene's
    /// size (by a power of two, exactly).
    Ulps,
}

impl Offset {
    /// A ray leaving point `p` of a surface with normal `side` (pointing to where the ray
    /// goes) in direction `dir`, up to `t_max`, in a scene whose largest extent is `size`.
    ///
    /// ```
    /// use quiver_scenes::render::Offset;
    /// use glam::Vec3A;
    /// let r = Offset::Epsilon.ray(10.0, Vec3A::ZERO, Vec3A::Z, Vec3A::Z, 1.0);
    /// assert!((r.t_min - 1e-4).abs() < 1e-9);
    /// // The same at a thousandth of the size, a thousandth of the distance.
    /// let small = Offset::Epsilon.ray(0.01, Vec3A::ZERO, Vec3A::Z, Vec3A::Z, 1.0);
    /// assert!((small.t_min - 1e-7).abs() < 1e-12);
    /// ```
    #[inline]
    pub fn ray(self, size: f32, p: Vec3A, side: Vec3A, dir: Vec3A, t_max: f32) -> Ray {
        match self {
            Offset::Epsilon => {
                let eps = 1e-4 * (0.1 * size + p.abs().max_element());
                Ray::segment(p, dir, eps / length(dir), t_max)
            }
            Offset::Ulps => {
                let unit = unit_of(size);
                let origin = offset_ray_origin(p / unit, side) * unit;
                Ray::segment(origin, dir, 0.0, t_max)
            }
        }
    }
}

/// `|v|` at any size (glam's squares overflow beyond about 1e19).
fn length(v: Vec3A) -> f32 {
    let l2 = v.length_squared();
    if l2.is_normal() {
        l2.sqrt()
    } else {
        v.dot(unit_or_zero(v))
    }
}

/// The power of two nearest below `size` (1 for a zero or non-finite size): dividing by it
/// is exact.
fn unit_of(size: f32) -> f32 {
    if size.is_normal() && size > 0.0 {
        f32::from_bits(size.to_bits() & 0x7f80_0000)
    } else {
        1.0
    }
}

/// A scene's size for [`Offset::ray`]: its largest extent.
///
/// ```
/// use quiver_scenes::{render::scene_size, Scene};
/// assert_eq!(scene_size(&Scene::load("tetra2").unwrap()), 2.0);
/// ```
pub fn scene_size(scene: &Scene) -> f32 {
    let b = scene.bounds();
    if b.is_empty() {
        1.0
    } else {
        b.extent().max_element()
    }
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            res: 512,
            max_depth: 5,
            two_sided: Vec::new(),
            counters: false,
            offset: Offset::Epsilon,
            packets: true,
            keep_image: true,
            eye_nodes: true,
            time_samples: 1,
        }
    }
}

/// The rays a render traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Eye rays (one per pixel corner).
    pub eye: u64,
    /// Eye rays that hit an object.
    pub eye_hit: u64,
    /// Reflection rays (from reflective surfaces, and on total internal reflection).
    pub reflect: u64,
    /// Refraction rays.
    pub refract: u64,
    /// Reflection and refraction rays that hit an object (with the eye hits and the blocked
    /// shadow rays, the rays that needed an intersection test: Havran's `r_SI · N_rays`).
    pub secondary_hit: u64,
    /// Shadow rays.
    pub shadow: u64,
    /// Shadow rays that found an occluder.
    pub shadow_blocked: u64,
}

impl RayCounts {
    /// All rays traced.
    pub fn total(&self) -> u64 {
        self.eye + self.reflect + self.refract + self.shadow
    }

    /// Rays whose answer needs at least one successful intersection test: eye and secondary
    /// rays that hit, shadow rays that are blocked (Havran's `r_SI · N_rays`).
    pub fn hits(&self) -> u64 {
        self.eye_hit + self.secondary_hit + self.shadow_blocked
    }
}

impl AddAssign for RayCounts {
    fn add_assign(&mut self, o: RayCounts) {
        self.eye += o.eye;
        self.eye_hit += o.eye_hit;
        self.reflect += o.reflect;
        self.refract += o.refract;
        self.secondary_hit += o.secondary_hit;
        self.shadow += o.shadow;
        self.shadow_blocked += o.shadow_blocked;
    }
}

/// What a render produced.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Width = height in pixels.
    pub res: u32,
    /// Pixels row by row from the top, 8-bit sRGB-less RGB (the SPD's colours are used as is);
    /// empty without [`RenderConfig::keep_image`].
    pub rgb: Vec<[u8; 3]>,
    /// A digest of the pixels (FNV-1a of each row, folded in row order), kept with or without
    /// the pixels: two renders with equal digests drew the same image.
    pub image_digest: u64,
    /// Rays traced, by kind.
    pub rays: RayCounts,
    /// Traversal work over all rays (zero unless [`RenderConfig::counters`]).
    pub work: Counters,
    /// Nodes visited by each eye ray, `(res + 1)^2` corners row by row (empty unless
    /// [`RenderConfig::counters`] and [`RenderConfig::eye_nodes`]). With packets, each eye ray
    /// is charged the node visits of its eye packet.
    pub eye_nodes: Vec<u32>,
    /// Rays the packet kernels traced (0 without [`RenderConfig::packets`]): eye rays, shadow
    /// rays and first-bounce reflection rays sent as packets whose rays point alike
    /// ([`PacketMode::Auto`]); the rest were traced ray by ray.
    pub packet_rays: u64,
}

/// Corner rows a render task handles, and the side of a packet's square of corners.
const TILE: usize = 8;

/// Tiles a packet render traces and shades together: their eye rays tile by tile, then each
/// light's shadow rays and the reflection rays gathered over the group. Small enough that the
/// group's surfaces and rays stay in the core's cache, large enough that most secondary
/// packets are full.
const GROUP: usize = 16;

/// What one band of [`TILE`] corner rows adds to the render's totals.
#[derive(Default)]
struct Tally {
    rays: RayCounts,
    work: Counters,
    packet_rays: u64,
}

/// The buffers a packet render fills for each tile group, kept from group to group so a
/// band allocates them once.
#[derive(Default)]
struct Scratch {
    /// Where each of the group's corners lies in its band (row-major), in tile order.
    slots: Vec<usize>,
    /// The group's eye rays and their closest hits, in tile order.
    eye: Vec<Ray>,
    eye_hits: Vec<Option<Hit>>,
    /// The corners whose eye ray hit something (indices into `slots`), and what they see.
    hit: Vec<usize>,
    surfaces: Vec<Surface>,
    /// `shadows[surface * lights + light]`: whether the shadow ray is blocked, `None` for a
    /// light the surface does not face.
    shadows: Vec<Option<bool>>,
    /// Per light, the surfaces that face it and their shadow rays.
    toward: Vec<(Vec<usize>, Vec<Ray>)>,
    blocked: Vec<bool>,
    /// Per surface, its reflection ray and that ray's hit, if it spawns one.
    reflections: Vec<Option<(Ray, Option<Hit>)>>,
    who: Vec<usize>,
    rays: Vec<Ray>,
    hits: Vec<Option<Hit>>,
}

/// Renders `scene` through `bvh` on the current rayon pool. `progress(rows)` is called as
/// corner rows complete (from worker threads). The result does not depend on the number of
/// threads: every corner is traced independently and the counts are integer sums.
pub fn render(
    scene: &Scene,
    bvh: &SceneBvh,
    config: &RenderConfig,
    progress: &(dyn Fn(usize) + Sync),
) -> Rendered {
    // The one place counting is decided: each choice compiles its own tracer.
    if config.counters {
        render_with::<Counters>(scene, bvh, config, progress)
    } else {
        render_with::<NoStats>(scene, bvh, config, progress)
    }
}

/// What a render records of the traversal: nothing ([`NoStats`]: the plain kernels) or the
/// work counts ([`Counters`]).
trait Work: Stats + Copy + Default + Send {
    /// Whether anything is counted (a constant, so uncounted renders skip the bookkeeping).
    const COUNTS: bool;
    /// The counts so far.
    fn counters(&self) -> Counters;
}

impl Work for NoStats {
    const COUNTS: bool = false;
    fn counters(&self) -> Counters {
        Counters::default()
    }
}

impl Work for Counters {
    const COUNTS: bool = true;
    fn counters(&self) -> Counters {
        *self
    }
}

fn render_with<W: Work>(
    scene: &Scene,
    bvh: &SceneBvh,
    config: &RenderConfig,
    progress: &(dyn Fn(usize) + Sync),
) -> Rendered {
    let n = config.res as usize + 1;
    let res = config.res as usize;
    let size = scene_size(scene);
    let bands = n.div_ceil(TILE);
    // Each band traces its corner rows into a buffer of its own and averages the pixel rows
    // whose four corners it holds; only its first and last corner rows are kept, for the
    // pixel row between it and the next band. So no buffer of every corner (16 bytes each:
    // 4.3 GB at 16384²) is ever held.
    let mut edges = vec![Vec3A::ZERO; bands * 2 * n];
    let mut rgb = vec![[0u8; 3]; if config.keep_image { res * res } else { 0 }];
    let mut digests = vec![0u64; res];
    let mut eye_nodes = vec![
        0u32;
        if W::COUNTS && config.eye_nodes {
            n * n
        } else {
            0
        }
    ];
    // Per band: its pixel rows, their digests, its eye rays' node counts (each `None` where
    // there are none) and its two edge rows.
    let mut jobs: Vec<BandOutputs> = Vec::with_capacity(bands);
    {
        let mut pixels = rgb.chunks_mut(TILE * res.max(1));
        let mut rows = digests.chunks_mut(TILE);
        let mut nodes = eye_nodes.chunks_mut(TILE * n);
        for edge in edges.chunks_mut(2 * n) {
            jobs.push(BandOutputs {
                pixels: pixels.next(),
                digests: rows.next(),
                eye_nodes: nodes.next(),
                edges: edge,
            });
        }
    }
    let tallies: Vec<Tally> = jobs
        .into_par_iter()
        .enumerate()
        .map(|(b, job)| {
            let rows = b * TILE..((b + 1) * TILE).min(n);
            let mut tracer = Tracer {
                scene,
                bvh,
                config,
                size,
                rays: RayCounts::default(),
                work: W::default(),
                packet_rays: 0,
            };
            let mut colors = vec![Vec3A::ZERO; rows.len() * n];
            tracer.band(
                rows.clone(),
                n,
                &mut colors,
                job.eye_nodes.unwrap_or_default(),
            );
            progress(rows.len());
            // The pixel rows within the band: row y between corner rows y and y + 1.
            let mut row = vec![[0u8; 3]; res];
            let digests = job.digests.unwrap_or_default();
            let mut pixels = job.pixels;
            for y in 0..rows
                .len()
                .saturating_sub(1)
                .min(res.saturating_sub(rows.start))
            {
                let (top, bottom) = (
                    &colors[y * n..(y + 1) * n],
                    &colors[(y + 1) * n..(y + 2) * n],
                );
                let out = match pixels.as_deref_mut() {
                    Some(p) => &mut p[y * res..(y + 1) * res],
                    None => &mut row[..],
                };
                pixel_row(top, bottom, out);
                digests[y] = fnv1a(out.as_flattened());
            }
            job.edges[..n].copy_from_slice(&colors[..n]);
            job.edges[n..].copy_from_slice(&colors[(rows.len() - 1) * n..]);
            Tally {
                rays: tracer.rays,
                work: tracer.work.counters(),
                packet_rays: tracer.packet_rays,
            }
        })
        .collect();
    // The pixel row between band b's last corner row and band b + 1's first: row 8b + 7.
    let seam = |b: usize| (b + 1) * TILE - 1;
    let mut seams: Vec<Seam> = Vec::new();
    {
        let mut pixels = rgb.chunks_mut(TILE * res.max(1));
        for (b, rows) in digests.chunks_mut(TILE).enumerate() {
            let p = pixels.next();
            if seam(b) < res {
                let local = seam(b) - b * TILE;
                let p = p.map(|p| &mut p[local * res..(local + 1) * res]);
                seams.push((b, p, &mut rows[local]));
            }
        }
    }
    seams.into_par_iter().for_each(|(b, pixels, digest)| {
        let top = &edges[b * 2 * n + n..(b + 1) * 2 * n];
        let bottom = &edges[(b + 1) * 2 * n..(b + 1) * 2 * n + n];
        let mut row = vec![[0u8; 3]; if pixels.is_some() { 0 } else { res }];
        let out = match pixels {
            Some(p) => p,
            None => &mut row[..],
        };
        pixel_row(top, bottom, out);
        *digest = fnv1a(out.as_flattened());
    });
    let mut rays = RayCounts::default();
    let mut work = Counters::default();
    let mut packet_rays = 0;
    for t in &tallies {
        rays += t.rays;
        work += t.work;
        packet_rays += t.packet_rays;
    }
    let image_digest = digests
        .iter()
        .fold(fnv1a(&(res as u64).to_le_bytes()), |h, &d| {
            (h ^ d).wrapping_mul(FNV_PRIME)
        });
    Rendered {
        res: config.res,
        rgb,
        image_digest,
        rays,
        work,
        eye_nodes,
        packet_rays,
    }
}

/// A seam's band, its pixel row (if the image is kept) and that row's digest.
type Seam<'a> = (usize, Option<&'a mut [[u8; 3]]>, &'a mut u64);

/// One band's share of the render's outputs (see `render_with`).
struct BandOutputs<'a> {
    /// Its [`TILE`] pixel rows (the last holds the seam with the next band), if kept.
    pixels: Option<&'a mut [[u8; 3]]>,
    digests: Option<&'a mut [u64]>,
    eye_nodes: Option<&'a mut [u32]>,
    /// Its first corner row, then its last.
    edges: &'a mut [Vec3A],
}

/// The time of corner `(i, j)`'s eye ray in sample `k` of `samples`: 0 for a single sample;
/// else within the sample's stratum `[k / samples, (k + 1) / samples)`, jittered by a hash
/// of the corner and sample (neighbouring corners differ, so the strata blur smoothly
/// instead of showing `samples` sharp copies, and a render repeats exactly).
fn shutter_sample(i: usize, j: usize, k: u32, samples: u32) -> f32 {
    if samples <= 1 {
        return 0.0;
    }
    // splitmix64's finaliser over the packed coordinates.
    let mut h = (i as u64) << 40 ^ (j as u64) << 16 ^ k as u64;
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^= h >> 31;
    let jitter = (h >> 40) as f32 / (1u64 << 24) as f32;
    (k as f32 + jitter) / samples as f32
}

/// Each pixel averages its four corners.
fn pixel_row(top: &[Vec3A], bottom: &[Vec3A], out: &mut [[u8; 3]]) {
    for (x, p) in out.iter_mut().enumerate() {
        let c = (top[x] + top[x + 1] + bottom[x] + bottom[x + 1]) * 0.25;
        *p = to_rgb8(c);
    }
}

const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a of `bytes`.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ b as u64).wrapping_mul(FNV_PRIME)
    })
}

fn to_rgb8(c: Vec3A) -> [u8; 3] {
    let q = |x: f32| (x.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c.x), q(c.y), q(c.z)]
}

/// Ambient light as a fraction of each surface's colour.
const AMBIENT: f32 = 0.1;

struct Tracer<'a, W> {
    scene: &'a Scene,
    bvh: &'a SceneBvh,
    config: &'a RenderConfig,
    /// The scene's size, for secondary-ray offsets.
    size: f32,
    rays: RayCounts,
    work: W,
    /// Rays traced by the packet kernels.
    packet_rays: u64,
}

/// What shading needs to know about a hit.
#[derive(Clone, Copy)]
struct Surface {
    /// Hit point.
    p: Vec3A,
    /// Unit direction of the incoming ray.
    d: Vec3A,
    material: Material,
    /// Geometric normal pointing out of the object.
    outward: Vec3A,
    /// Shading normal: `outward`, turned toward the viewer on two-sided surfaces.
    n: Vec3A,
    /// The incoming ray's time: every ray leaving the surface is shot then.
    time: f32,
}

/// A packet query and where its answers go.
enum Query<'o> {
    Closest(&'o mut [Option<Hit>]),
    Any(&'o mut [bool]),
}

impl Query<'_> {
    /// Runs the query packet by packet, each packet down the packet kernel or ray by ray as
    /// [`PacketMode::Auto`] would send it (decided here, once, so the query does not check
    /// again); returns the rays traced as packets.
    fn run<S: Stats>(self, bvh: &SceneBvh, rays: &[Ray], stats: &mut S) -> u64 {
        let mut packet_rays = 0;
        let mode = |rays: &[Ray], packet_rays: &mut u64| {
            let n = PacketMode::Auto.packet_rays(rays, None);
            *packet_rays += n;
            if n > 0 {
                PacketMode::Always
            } else {
                PacketMode::Never
            }
        };
        match self {
            Query::Closest(hits) => {
                for (r, h) in rays.chunks(PACKET_RAYS).zip(hits.chunks_mut(PACKET_RAYS)) {
                    let m = mode(r, &mut packet_rays);
                    bvh.closest_hit_packet_with::<ConservativeBoxes, S, _>(
                        PacketQuery::new(r).mode(m),
                        h,
                        stats,
                        &mut NoFilter,
                    );
                }
            }
            Query::Any(blocked) => {
                for (r, o) in rays
                    .chunks(PACKET_RAYS)
                    .zip(blocked.chunks_mut(PACKET_RAYS))
                {
                    let m = mode(r, &mut packet_rays);
                    bvh.any_hit_packet_with::<ConservativeBoxes, S, _>(
                        PacketQuery::new(r).mode(m),
                        o,
                        stats,
                        &mut NoFilter,
                    );
                }
            }
        }
        packet_rays
    }
}

/// Where a surface learns what its first secondary rays see.
enum Secondary<'s> {
    /// Trace each shadow and reflection ray now.
    Trace,
    /// Already traced (as packets): per light, whether the shadow ray toward it is blocked
    /// (`None` for a light the surface does not face), and the reflection ray with its hit if
    /// the surface spawns one. The rays are not made again.
    Known {
        shadows: &'s [Option<bool>],
        reflection: Option<(Ray, Option<Hit>)>,
    },
}

impl<W: Work> Tracer<'_, W> {
    /// Colours the corners of rows `rows` (of `n` corners each) into `colors` (row-major):
    /// eye rays in packets of `TILE x TILE` corners, or one by one. When counting, writes the
    /// nodes each eye ray visited into `eye_nodes` (row-major) unless it is empty.
    fn band(&mut self, rows: Range<usize>, n: usize, colors: &mut [Vec3A], eye_nodes: &mut [u32]) {
        let samples = self.config.time_samples.max(1);
        if samples == 1 {
            return self.band_at(rows, n, colors, eye_nodes, 0);
        }
        let mut sum = vec![Vec3A::ZERO; colors.len()];
        for k in 0..samples {
            self.band_at(rows.clone(), n, colors, eye_nodes, k);
            for (a, c) in sum.iter_mut().zip(colors.iter()) {
                *a += *c;
            }
        }
        for (c, a) in colors.iter_mut().zip(&sum) {
            *c = *a / samples as f32;
        }
    }

    /// [`Tracer::band`] for time sample `sample` of [`RenderConfig::time_samples`].
    #[inline(never)]
    fn band_at(
        &mut self,
        rows: Range<usize>,
        n: usize,
        colors: &mut [Vec3A],
        eye_nodes: &mut [u32],
        sample: u32,
    ) {
        // Node counts are kept only where the caller gave room for them.
        let keep = W::COUNTS && !eye_nodes.is_empty();
        let view = self.scene.camera.view();
        let res = self.config.res as f32;
        let across: Vec<Vec3A> = (0..n)
            .map(|i| view.across(-1.0 + 2.0 * i as f32 / res))
            .collect();
        let down: Vec<Vec3A> = rows
            .clone()
            .map(|j| view.down(1.0 - 2.0 * j as f32 / res))
            .collect();
        let hither = self.scene.hither.max(0.0);
        let samples = self.config.time_samples.max(1);
        let eye = |i: usize, j: usize| {
            let mut ray = view.ray_through(across[i], down[j - rows.start]);
            ray.t_min = hither;
            ray.time = shutter_sample(i, j, sample, samples);
            ray
        };
        if !self.config.packets {
            for j in rows.clone() {
                for i in 0..n {
                    let ray = eye(i, j);
                    let before = self.work.counters().nodes;
                    let hit = self.closest(&ray);
                    let k = (j - rows.start) * n + i;
                    if keep {
                        eye_nodes[k] = (self.work.counters().nodes - before) as u32;
                    }
                    let s = hit.map(|h| self.surface(&ray, &h));
                    colors[k] = self.color(s, 1, Secondary::Trace);
                }
            }
            return;
        }
        let mut sc = Scratch::default();
        for x0 in (0..n).step_by(TILE * GROUP) {
            sc.slots.clear();
            sc.eye.clear();
            for t0 in (x0..(x0 + TILE * GROUP).min(n)).step_by(TILE) {
                let from = sc.eye.len();
                for j in rows.clone() {
                    for i in t0..(t0 + TILE).min(n) {
                        sc.slots.push((j - rows.start) * n + i);
                        sc.eye.push(eye(i, j));
                    }
                }
                sc.eye_hits.resize(sc.eye.len(), None);
                let before = self.work.counters().nodes;
                self.packet_query(&sc.eye[from..], Query::Closest(&mut sc.eye_hits[from..]));
                if keep {
                    let nodes = (self.work.counters().nodes - before) as u32;
                    for &k in &sc.slots[from..] {
                        eye_nodes[k] = nodes;
                    }
                }
            }
            sc.hit.clear();
            sc.surfaces.clear();
            for (k, (r, h)) in sc.eye.iter().zip(&sc.eye_hits).enumerate() {
                match h {
                    Some(h) => {
                        sc.hit.push(k);
                        sc.surfaces.push(self.surface(r, h));
                    }
                    None => colors[sc.slots[k]] = self.color(None, 1, Secondary::Trace),
                }
            }
            self.shade_group(&mut sc, colors);
        }
    }

    /// Colours the surfaces a tile group's eye rays hit into `colors`. Their shadow rays,
    /// light by light, and their reflection rays go as packets, gathered over the group so
    /// that most packets are full: only the rays the surfaces call for (a light the surface
    /// faces, a reflective or transmitting material), in tile order, so neighbouring rays
    /// share a packet. Everything after the first bounce is traced ray by ray.
    fn shade_group(&mut self, sc: &mut Scratch, colors: &mut [Vec3A]) {
        let lights = self.scene.lights.len();
        let m = sc.surfaces.len();
        sc.toward.resize_with(lights, Default::default);
        for (who, rays) in &mut sc.toward {
            who.clear();
            rays.clear();
        }
        // One pass over the surfaces for all lights.
        for (k, s) in sc.surfaces.iter().enumerate() {
            for (light, (who, rays)) in self.scene.lights.iter().zip(&mut sc.toward) {
                if let Some(r) = self.shadow_ray(s, light.pos) {
                    who.push(k);
                    rays.push(r);
                }
            }
        }
        sc.shadows.clear();
        sc.shadows.resize(m * lights, None);
        for l in 0..lights {
            let (who, rays) = &sc.toward[l];
            sc.blocked.clear();
            sc.blocked.resize(rays.len(), false);
            self.packet_query(rays, Query::Any(&mut sc.blocked));
            for (&k, &a) in who.iter().zip(&sc.blocked) {
                sc.shadows[k * lights + l] = Some(a);
            }
        }
        sc.reflections.clear();
        sc.reflections.resize(m, None);
        if self.config.max_depth > 1 {
            sc.who.clear();
            sc.rays.clear();
            for (k, s) in sc.surfaces.iter().enumerate() {
                if let Some(r) = self.reflection_ray(s) {
                    sc.who.push(k);
                    sc.rays.push(r);
                }
            }
            sc.hits.clear();
            sc.hits.resize(sc.rays.len(), None);
            self.packet_query(&sc.rays, Query::Closest(&mut sc.hits));
            for ((&k, &r), &h) in sc.who.iter().zip(&sc.rays).zip(&sc.hits) {
                sc.reflections[k] = Some((r, h));
            }
        }
        for (k, &corner) in sc.hit.iter().enumerate() {
            let known = Secondary::Known {
                shadows: &sc.shadows[k * lights..(k + 1) * lights],
                reflection: sc.reflections[k],
            };
            colors[sc.slots[corner]] = self.color(Some(sc.surfaces[k]), 1, known);
        }
    }

    /// A packet query through the packet kernels, recording into `work`.
    fn packet_query(&mut self, rays: &[Ray], query: Query) {
        self.packet_rays += query.run(self.bvh, rays, &mut self.work);
    }

    /// Closest hit, recording into `work`.
    fn closest(&mut self, ray: &Ray) -> Option<Hit> {
        self.bvh
            .closest_hit_with::<ConservativeBoxes, W, _>(ray, &mut self.work, &mut NoFilter)
    }

    /// Whether anything blocks `ray`, recording into `work`.
    fn occluded(&mut self, ray: &Ray) -> bool {
        self.bvh
            .any_hit_with::<ConservativeBoxes, W, _>(ray, &mut self.work, &mut NoFilter)
    }

    /// Colour seen along `ray`, a secondary ray of generation `depth`.
    fn trace(&mut self, ray: &Ray, depth: u32) -> Vec3A {
        let hit = self.closest(ray);
        self.traced(ray, hit, depth)
    }

    /// Colour seen along `ray`, a secondary ray of generation `depth` whose closest hit
    /// is `hit`.
    fn traced(&mut self, ray: &Ray, hit: Option<Hit>, depth: u32) -> Vec3A {
        let s = hit.map(|h| self.surface(ray, &h));
        self.rays.secondary_hit += s.is_some() as u64;
        self.color(s, depth, Secondary::Trace)
    }

    /// Colour seen by a ray of generation `depth` that found surface `s` (or nothing);
    /// counts eye rays and their hits at depth 1.
    fn color(&mut self, s: Option<Surface>, depth: u32, known: Secondary) -> Vec3A {
        if depth == 1 {
            self.rays.eye += 1;
            self.rays.eye_hit += s.is_some() as u64;
        }
        match s {
            Some(s) => self.shade_surface(&s, depth, known),
            None => self.scene.background,
        }
    }

    fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        let object = &self.scene.objects[self.bvh.object_of(hit.prim) as usize];
        let material = self.scene.materials[object.material as usize];
        let d = unit_or_zero(ray.dir);
        // The outward normal decides entering or leaving a transmitter; the shading normal
        // turns toward the viewer on two-sided surfaces: transmitters (NFF: "objects with
        // T > 0 are two-sided") and the materials the config lists (the teapot).
        let outward = self.bvh.normal(ray, hit);
        let two_sided = material.t > 0.0 || self.config.two_sided.contains(&object.material);
        let n = if two_sided && outward.dot(d) > 0.0 {
            -outward
        } else {
            outward
        };
        Surface {
            p: ray.at(hit.t),
            d,
            material,
            outward,
            n,
            time: ray.time,
        }
    }

    /// The shadow ray from `s` toward a light at `light`, up to just short of it; `None` when
    /// the light is behind the surface (SPD rule 10, transmitters too).
    fn shadow_ray(&self, s: &Surface, light: Vec3A) -> Option<Ray> {
        let to_light = light - s.p;
        (s.n.dot(to_light) > 0.0).then(|| {
            let r = self.config.offset.ray(self.size, s.p, s.n, to_light, 1.0);
            r.with_time(s.time)
        })
    }

    /// The reflection ray off `s`, if its material spawns one: reflective and transmitting
    /// surfaces both do (SPD rule 8; the gears' glass has Ks = 0 and still reflects).
    fn reflection_ray(&self, s: &Surface) -> Option<Ray> {
        if !(s.material.ks > 0.0 || s.material.t > 0.0) {
            return None;
        }
        let (nf, _) = facing(s);
        let dir = s.d - nf * (2.0 * s.d.dot(nf));
        Some(
            self.config
                .offset
                .ray(self.size, s.p, nf, dir, f32::INFINITY)
                .with_time(s.time),
        )
    }

    /// Colour leaving `s` toward the viewer: lights, then reflection and refraction rays.
    fn shade_surface(&mut self, s: &Surface, depth: u32, known: Secondary) -> Vec3A {
        let m = s.material;
        let (p, d, n) = (s.p, s.d, s.n);
        let offset = self.config.offset;
        let mut color = m.color * AMBIENT;
        let intensity = 1.0 / (self.scene.lights.len().max(1) as f32).sqrt();
        for (i, l) in self.scene.lights.iter().enumerate() {
            let blocked = match known {
                Secondary::Trace => self.shadow_ray(s, l.pos).map(|r| self.occluded(&r)),
                Secondary::Known { shadows, .. } => shadows[i],
            };
            let Some(blocked) = blocked else {
                continue;
            };
            self.rays.shadow += 1;
            if blocked {
                self.rays.shadow_blocked += 1;
                continue;
            }
            color += shade(&m, n, unit_or_zero(l.pos - p), d) * l.color * intensity;
        }
        if depth >= self.config.max_depth {
            return color;
        }
        // Facing the incoming ray, for reflection and refraction.
        let (nf, entering) = facing(s);
        // The reflected ray carries Ks, and on total internal reflection also the T the
        // refracted ray would have carried.
        let mut reflect_weight = m.ks;
        if m.t > 0.0 {
            let eta = if entering { 1.0 / m.ior } else { m.ior };
            let cos_i = -d.dot(nf);
            let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
            if k >= 0.0 {
                self.rays.refract += 1;
                let dir = d * eta + nf * (eta * cos_i - k.sqrt());
                let r = offset
                    .ray(self.size, p, -nf, dir, f32::INFINITY)
                    .with_time(s.time);
                color += self.trace(&r, depth + 1) * m.t;
            } else {
                // Total internal reflection: the reflection ray takes the transmitted share.
                reflect_weight += m.t;
            }
        }
        let reflection = match known {
            Secondary::Trace => self.reflection_ray(s).map(|r| (r, self.closest(&r))),
            Secondary::Known { reflection, .. } => reflection,
        };
        if let Some((r, hit)) = reflection {
            self.rays.reflect += 1;
            color += self.traced(&r, hit, depth + 1) * reflect_weight;
        }
        color
    }
}

/// The surface's outward normal turned to face the incoming ray, and whether the ray enters
/// the object (meets the outward side).
fn facing(s: &Surface) -> (Vec3A, bool) {
    if s.outward.dot(s.d) < 0.0 {
        (s.outward, true)
    } else {
        (-s.outward, false)
    }
}

/// Diffuse plus, on reflective surfaces, a Phong highlight.
fn shade(m: &Material, n: Vec3A, l: Vec3A, d: Vec3A) -> Vec3A {
    let mut c = m.color * (m.kd * n.dot(l).max(0.0));
    if m.ks > 0.0 {
        let r = l - n * (2.0 * l.dot(n));
        let spec = r.dot(d).max(0.0).powf(m.shine.max(1.0));
        c += Vec3A::splat(m.ks * spec);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use quiver_rt::BuildOptions;

    /// The renderer before issue 29 kept every corner's colour and averaged pixels from that
    /// buffer; this is that averaging, over corners traced by the same bands.
    fn full_buffer_pixels(scene: &Scene, bvh: &SceneBvh, config: &RenderConfig) -> Vec<[u8; 3]> {
        let n = config.res as usize + 1;
        let res = config.res as usize;
        let size = scene_size(scene);
        let mut corners = vec![Vec3A::ZERO; n * n];
        for (b, colors) in corners.chunks_mut(TILE * n).enumerate() {
            let rows = b * TILE..((b + 1) * TILE).min(n);
            let mut tracer = Tracer {
                scene,
                bvh,
                config,
                size,
                rays: RayCounts::default(),
                work: NoStats,
                packet_rays: 0,
            };
            tracer.band(rows, n, colors, &mut []);
        }
        let mut rgb = vec![[0u8; 3]; res * res];
        for (y, pixels) in rgb.chunks_mut(res.max(1)).enumerate() {
            let (top, bottom) = (&corners[y * n..], &corners[(y + 1) * n..]);
            for (x, p) in pixels.iter_mut().enumerate() {
                let c = (top[x] + top[x + 1] + bottom[x] + bottom[x + 1]) * 0.25;
                *p = to_rgb8(c);
            }
        }
        rgb
    }

    /// Pixels averaged band by band, seams between bands included, equal the full corner
    /// buffer's at every resolution around a band's size; the digest without the image is
    /// the digest with it, and differs when a pixel does.
    #[test]
    fn band_pixels_equal_the_full_corner_buffer() {
        let scene = Scene::load("teapot3").unwrap();
        let bvh = SceneBvh::build(&scene, &BuildOptions::default()).unwrap();
        let mut digests = Vec::new();
        for res in (1..=18).chain([23, 24, 25, 40, 63, 64, 65]) {
            for packets in [false, true] {
                let config = RenderConfig {
                    res,
                    packets,
                    ..RenderConfig::default()
                };
                let out = render(&scene, &bvh, &config, &|_| {});
                assert_eq!(
                    out.rgb,
                    full_buffer_pixels(&scene, &bvh, &config),
                    "res {res}"
                );
                let lean = RenderConfig {
                    keep_image: false,
                    ..config.clone()
                };
                let no_image = render(&scene, &bvh, &lean, &|_| {});
                assert!(no_image.rgb.is_empty());
                assert_eq!(no_image.image_digest, out.image_digest, "res {res}");
                assert_eq!(no_image.rays, out.rays);
                digests.push(out.image_digest);
            }
        }
        // Different images (resolutions), different digests; packets on and off alike.
        for pair in digests.chunks(2) {
            assert_eq!(pair[0], pair[1]);
        }
        let mut distinct: Vec<u64> = digests.iter().step_by(2).copied().collect();
        distinct.sort_unstable();
        distinct.dedup();
        assert_eq!(distinct.len(), digests.len() / 2);
    }

    /// Node counts per eye ray are kept only when asked, and then for every corner.
    #[test]
    fn eye_nodes_only_when_asked() {
        let scene = Scene::load("tetra2").unwrap();
        let bvh = SceneBvh::build(&scene, &BuildOptions::default()).unwrap();
        for eye_nodes in [false, true] {
            let config = RenderConfig {
                res: 20,
                counters: true,
                eye_nodes,
                ..RenderConfig::default()
            };
            let out = render(&scene, &bvh, &config, &|_| {});
            assert_eq!(out.eye_nodes.len(), if eye_nodes { 21 * 21 } else { 0 });
            if eye_nodes {
                assert!(out.eye_nodes.iter().all(|&n| n > 0));
            }
        }
    }
}
