//! Saving a [`World`] of triangles and loading it back: [`World::save`], [`World::to_bytes`],
//! [`World::load`], [`World::from_bytes`].
//!
//! The format (`docs/file-format.md` has the byte table): a 32-byte header (magic, format
//! version, endianness marker, geometry and instance counts), then each geometry (its kind,
//! its triangles in input order, then its BVH as one whole BVH file, [`Bvh::save`]'s bytes;
//! a moving mesh its steps' triangles, its trees built again at load),
//! then the instances (64 bytes each: geometry, mask, user id, flags, transform), then each
//! moving instance's motion (interpolation, key count, keys), then a checksum of everything
//! before it. The top level is not stored: loading builds it again
//! (a few milliseconds per ten thousand instances), from the same instances, as
//! [`super::WorldBuilder::build`] would. Filters are code and are not stored either: set them
//! again after loading ([`super::WorldEdit::set_filter`]).

use super::builder::{set_slot, Placed};
use super::deform::check_steps;
use super::instance::placements;
use super::{
    Geometry, GeometryId, Instance, InstanceId, Interpolation, Motion, MovingTriangles, World,
    WorldError, MAX_MOTION_KEYS,
};
use crate::bvh::{BuildOptions, Bvh};
use crate::geometry::Triangle;
use crate::save::{
    checksum, input_count, preamble, read_triangles, saved_len, Hashing, ENDIAN, TRIANGLE_BYTES,
};
use crate::LoadError;
use glam::Affine3A;
use std::io::{self, Read, Write};

/// The first eight bytes of a world file (a BVH file's are `QUIVBVH\x1a`).
const MAGIC: [u8; 8] = *b"QUIVWLD\x1a";

/// Bytes of the header.
const HEAD: usize = 32;

/// Bytes before a geometry's triangles: its kind, four reserved zero bytes, its count.
const GEOMETRY_HEAD: usize = 16;

/// Bytes of one instance: geometry, mask, user id, flags (u32 each), then the transform's
/// twelve f32 (the columns of the linear part, then the translation).
const INSTANCE_BYTES: usize = 64;

/// The instance flags (the record's fourth word): removed by an edit; moving (its motion
/// follows the instance table, in instance order).
const FLAG_REMOVED: u32 = 1;
const FLAG_MOVING: u32 = 2;

/// A motion's interpolation in the file.
const MOTION_LINEAR: u32 = 0;
const MOTION_DECOMPOSED: u32 = 1;

/// A geometry's kind in the file.
const KIND_TRIANGLES: u32 = 0;
const KIND_PRIMS: u32 = 1;
/// A moving mesh (format version 2 on): its step count, then each step's triangle count and
/// triangles; no BVH (its segments' trees are built again at load).
const KIND_MOVING: u32 = 2;

/// The first world format version that holds moving meshes (version 1 is version 2 without
/// [`KIND_MOVING`]).
const MOVING_VERSION: u32 = 2;

/// Bytes of a step's head: its triangle count (u64).
const STEP_HEAD: u64 = 8;

impl World {
    /// The newest world file format version this quiver writes and reads (it reads every
    /// version from 1 on). Version 2 adds moving meshes ([`Geometry::MovingTriangles`]) and is
    /// written only for a world holding one: any other world is written as version 1, byte
    /// for byte as before, so older quivers read it.
    ///
    /// ```
    /// assert_eq!(quiver_rt::World::FORMAT_VERSION, 2);
    /// ```
    pub const FORMAT_VERSION: u32 = MOVING_VERSION;

    /// Writes the world to `w`: every geometry (its triangles and its BVH as
    /// [`Bvh::save`] writes it), every instance (removed ones included, so ids stay), and a
    /// checksum. Filters are not written (they are code); the top level is built again by
    /// [`World::load`].
    ///
    /// ```
    /// use quiver_rt::glam::{Affine3A, Vec3, Vec3A};
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// b.add_instance(Instance::of(g));
    /// b.add_instance(Instance::of(g).transform(Affine3A::from_translation(Vec3::Z)).user_id(7));
    /// let world = b.build(&BuildOptions::default())?;
    /// let mut file = Vec::new();
    /// world.save(&mut file)?;
    /// let loaded = World::load(&mut &file[..])?;
    /// let ray = Ray::new(Vec3A::new(0.2, 0.2, 5.0), -Vec3A::Z);
    /// assert_eq!(loaded.closest_hit(&ray), world.closest_hit(&ray));
    /// assert_eq!(loaded.instances(), world.instances());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// A moving mesh ([`Geometry::MovingTriangles`]) is stored as its steps' triangles (the
    /// file is then of version 2, [`World::FORMAT_VERSION`]); its trees are built again at
    /// load, as [`super::WorldBuilder::build`] builds them, so a mesh refit by an edit
    /// ([`super::WorldEdit::refit_moving_triangles`]) loads with fresh trees (the same hits,
    /// but two at the same distance may be reported the other way round).
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::{BuildOptions, Instance, Ray, RayQuery, Triangle, World};
    /// let tri = |z: f32| Triangle::new(Vec3A::new(0.0, 0.0, z), Vec3A::X, Vec3A::Y);
    /// let mut b = World::builder();
    /// let g = b.add_moving_triangles(vec![vec![tri(0.0)], vec![tri(-2.0)], vec![tri(-1.0)]])?;
    /// b.add_instance(Instance::of(g));
    /// let world = b.build(&BuildOptions::default())?;
    /// let bytes = world.to_bytes();
    /// assert_eq!(bytes[8..12], 2u32.to_le_bytes()); // version 2: a moving mesh
    /// let loaded = World::from_bytes(&bytes)?;
    /// let ray = Ray::new(Vec3A::new(0.1, 0.1, 1.0), -Vec3A::Z).with_time(0.3);
    /// assert_eq!(loaded.closest_hit(&ray), world.closest_hit(&ray));
    /// assert_eq!(loaded.to_bytes(), bytes);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// What `w` returns.
    pub fn save<W: Write + ?Sized>(&self, w: &mut W) -> io::Result<()> {
        let moving = self
            .geometries
            .iter()
            .any(|g| matches!(g, Geometry::MovingTriangles(_)));
        let version = if moving { MOVING_VERSION } else { 1 };
        let mut out = Hashing::new(w);
        let mut head = [0u8; HEAD];
        head[..8].copy_from_slice(&MAGIC);
        head[8..12].copy_from_slice(&version.to_le_bytes());
        head[12..16].copy_from_slice(&ENDIAN.to_ne_bytes());
        head[16..24].copy_from_slice(&(self.geometries.len() as u64).to_le_bytes());
        head[24..32].copy_from_slice(&(self.instances.len() as u64).to_le_bytes());
        out.put(&head)?;
        for g in &self.geometries {
            let (kind, bvh, tris) = match g {
                Geometry::Triangles(b, t) => (KIND_TRIANGLES, b, t),
                Geometry::Prims(b, t) => (KIND_PRIMS, b, t),
                Geometry::MovingTriangles(m) => {
                    let mut gh = [0u8; GEOMETRY_HEAD + 8];
                    gh[..4].copy_from_slice(&KIND_MOVING.to_le_bytes());
                    gh[8..16].copy_from_slice(&(m.len() as u64).to_le_bytes());
                    gh[16..].copy_from_slice(&(m.steps().len() as u64).to_le_bytes());
                    out.put(&gh)?;
                    for step in m.steps() {
                        out.put(&(step.len() as u64).to_le_bytes())?;
                        out.put_triangles(step)?;
                    }
                    continue;
                }
            };
            let mut gh = [0u8; GEOMETRY_HEAD];
            gh[..4].copy_from_slice(&kind.to_le_bytes());
            gh[8..].copy_from_slice(&(tris.len() as u64).to_le_bytes());
            out.put(&gh)?;
            out.put_triangles(tris)?;
            bvh.save(&mut out)?;
        }
        for (i, inst) in self.instances.iter().enumerate() {
            let removed = u32::from(self.removed.get(i) == Some(&true));
            let moving = u32::from(self.motion(InstanceId(i as u32)).is_some());
            let mut words = [0u32; INSTANCE_BYTES / 4];
            words[..4].copy_from_slice(&[
                inst.geometry.0,
                inst.mask,
                inst.user_id,
                (removed * FLAG_REMOVED) | (moving * FLAG_MOVING),
            ]);
            words[4..].copy_from_slice(&inst.transform.to_cols_array().map(f32::to_bits));
            out.put(bytemuck::cast_slice(&words.map(u32::to_le)[..]))?;
        }
        for m in self.motions.iter().flatten() {
            let kind = match m.interpolation() {
                Interpolation::Linear => MOTION_LINEAR,
                Interpolation::Decomposed => MOTION_DECOMPOSED,
            };
            out.put(bytemuck::cast_slice(
                &[kind, m.keys().len() as u32].map(u32::to_le)[..],
            ))?;
            for key in m.keys() {
                out.put(bytemuck::cast_slice(
                    &key.to_cols_array().map(|f| f.to_bits().to_le())[..],
                ))?;
            }
        }
        out.finish()
    }

    /// The world as the bytes [`World::save`] writes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        self.save(&mut out).expect("writing to a Vec does not fail");
        out
    }

    /// Reads a world [`World::save`] wrote from `r`, to the reader's end, and checks it as
    /// [`World::from_bytes`] does. Memory grows with the bytes actually read, never with
    /// lengths the file only claims.
    ///
    /// # Errors
    /// [`LoadError`]: the reader's error, or what is wrong with the bytes.
    pub fn load<R: Read + ?Sized>(r: &mut R) -> Result<World, LoadError> {
        let mut bytes = Vec::new();
        r.read_to_end(&mut bytes)?;
        Self::from_bytes(&bytes)
    }

    /// The world in `bytes`, which hold exactly one file [`World::save`] wrote. Nothing is
    /// trusted: the header, the checksum, every length against the bytes present (before
    /// anything is allocated for it), every geometry's BVH as [`Bvh::from_bytes`] checks it
    /// and against the geometry's triangle count, every instance's geometry and transform as
    /// [`super::WorldBuilder::build`] checks them. The top level is then built, on the current
    /// rayon pool; the kernels are the best this CPU runs.
    ///
    /// ```
    /// use quiver_rt::glam::Vec3A;
    /// use quiver_rt::{BuildOptions, Instance, LoadError, Triangle, World};
    /// let mut b = World::builder();
    /// let g = b.add_triangles(vec![Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::Y)]);
    /// b.add_instance(Instance::of(g));
    /// let mut bytes = b.build(&BuildOptions::default())?.to_bytes();
    /// assert_eq!(World::from_bytes(&bytes)?.instances().len(), 1);
    /// let n = bytes.len();
    /// bytes[n - 20] ^= 1; // a bit of the instance's transform
    /// assert!(matches!(World::from_bytes(&bytes), Err(LoadError::Checksum { .. })));
    /// assert!(matches!(World::from_bytes(&bytes[..n - 9]), Err(LoadError::Checksum { .. })));
    /// assert!(matches!(World::from_bytes(b"QUIVBVH\x1a"), Err(LoadError::BadMagic)));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`LoadError`], naming what is wrong and where.
    pub fn from_bytes(bytes: &[u8]) -> Result<World, LoadError> {
        let have = bytes.len() as u64;
        let version = preamble(bytes, &MAGIC, (HEAD + 8) as u64, World::FORMAT_VERSION)?;
        if bytes.len() < HEAD + 8 {
            return Err(LoadError::Truncated {
                section: "header",
                need: (HEAD + 8) as u64,
                have,
            });
        }
        let long = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        let end = bytes.len() - 8;
        let (stored, computed) = (long(end), checksum(&bytes[..end]));
        if stored != computed {
            return Err(LoadError::Checksum { stored, computed });
        }
        let (geometries_n, instances_n) = (long(16), long(24));
        let mut at = Cursor {
            bytes: &bytes[..end],
            at: HEAD,
            version,
        };
        // Each geometry takes at least its head: the count is bounded by the bytes present.
        let mut geometries =
            Vec::with_capacity(geometries_n.min(have / GEOMETRY_HEAD as u64) as usize);
        for k in 0..geometries_n {
            geometries.push(at.geometry(k as usize)?);
        }
        let n =
            instances_n
                .checked_mul(INSTANCE_BYTES as u64)
                .ok_or(LoadError::LengthOverflow {
                    section: "instances",
                })?;
        let table = at.take(n, "instances")?;
        let mut instances = Vec::with_capacity(table.len() / INSTANCE_BYTES);
        let mut removed = Vec::with_capacity(table.len() / INSTANCE_BYTES);
        let mut moving = Vec::new();
        for (i, b) in table.chunks_exact(INSTANCE_BYTES).enumerate() {
            let w: [u32; INSTANCE_BYTES / 4] = std::array::from_fn(|k| {
                u32::from_le_bytes(b[4 * k..4 * k + 4].try_into().unwrap())
            });
            let transform =
                Affine3A::from_cols_array(&std::array::from_fn(|k| f32::from_bits(w[4 + k])));
            instances.push(Instance {
                geometry: GeometryId(w[0]),
                transform,
                mask: w[1],
                user_id: w[2],
            });
            if w[3] & !(FLAG_REMOVED | FLAG_MOVING) != 0 {
                return Err(LoadError::BadHeader {
                    field: "instance flags",
                    value: w[3].into(),
                });
            }
            removed.push(w[3] & FLAG_REMOVED != 0);
            if w[3] & FLAG_MOVING != 0 {
                moving.push(i);
            }
        }
        let mut motions = Vec::new();
        for i in moving {
            set_slot(&mut motions, i, Some(at.motion()?));
        }
        if at.at != end {
            return Err(LoadError::TrailingBytes {
                extra: (end - at.at) as u64,
            });
        }
        if !removed.contains(&true) {
            removed.clear();
        }
        let leaves =
            placements(&instances, &motions, geometries.len()).map_err(LoadError::World)?;
        let placed = Placed {
            geometries,
            instances,
            motions,
            removed,
            leaves,
        };
        Ok(placed.world(&BuildOptions::default()))
    }
}

/// Reading a world file's body front to back, every length checked against what is left.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
    /// The file's format version.
    version: u32,
}

impl<'a> Cursor<'a> {
    /// The next `n` bytes (`section` names them when they are not all there).
    fn take(&mut self, n: u64, section: &'static str) -> Result<&'a [u8], LoadError> {
        let left = (self.bytes.len() - self.at) as u64;
        if n > left {
            return Err(LoadError::Truncated {
                section,
                need: self.at as u64 + n,
                have: self.bytes.len() as u64,
            });
        }
        let out = &self.bytes[self.at..self.at + n as usize];
        self.at += n as usize;
        Ok(out)
    }

    /// A moving instance's motion: its interpolation, its key count, its keys.
    fn motion(&mut self) -> Result<Motion, LoadError> {
        let head = self.take(8, "motion head")?;
        let word = |at: usize| u32::from_le_bytes(head[at..at + 4].try_into().unwrap());
        let (kind, count) = (word(0), word(4));
        if count as usize > MAX_MOTION_KEYS {
            return Err(LoadError::BadHeader {
                field: "motion key count",
                value: count.into(),
            });
        }
        let keys: Vec<Affine3A> = self
            .take(u64::from(count) * 48, "motion keys")?
            .chunks_exact(48)
            .map(|k| {
                Affine3A::from_cols_array(&std::array::from_fn(|j| {
                    f32::from_le_bytes(k[4 * j..4 * j + 4].try_into().unwrap())
                }))
            })
            .collect();
        match kind {
            MOTION_LINEAR => Ok(Motion::linear(keys)),
            MOTION_DECOMPOSED => Ok(Motion::decomposed(keys)),
            _ => Err(LoadError::BadHeader {
                field: "motion interpolation",
                value: kind.into(),
            }),
        }
    }

    /// Geometry `k`: its head, its triangles, its BVH.
    fn geometry(&mut self, k: usize) -> Result<Geometry, LoadError> {
        let head = self.take(GEOMETRY_HEAD as u64, "geometry head")?;
        let kind = u32::from_le_bytes(head[..4].try_into().unwrap());
        let reserved = u32::from_le_bytes(head[4..8].try_into().unwrap());
        let count = u64::from_le_bytes(head[8..].try_into().unwrap());
        let newest = match self.version >= MOVING_VERSION {
            true => KIND_MOVING,
            false => KIND_PRIMS,
        };
        if kind > newest {
            return Err(LoadError::BadHeader {
                field: "geometry kind",
                value: kind.into(),
            });
        }
        if reserved != 0 {
            return Err(LoadError::BadHeader {
                field: "geometry reserved",
                value: reserved.into(),
            });
        }
        let n = count
            .checked_mul(TRIANGLE_BYTES as u64)
            .ok_or(LoadError::LengthOverflow {
                section: "geometry triangles",
            })?;
        if kind == KIND_MOVING {
            return self.moving(k, count, n);
        }
        let tris: Vec<Triangle> = read_triangles(self.take(n, "geometry triangles")?);
        let rest = &self.bytes[self.at..];
        let in_geometry = |error| LoadError::InGeometry {
            geometry: k,
            error: Box::new(error),
        };
        let len = saved_len(rest).map_err(in_geometry)?;
        let file = self.take(len, "geometry BVH")?;
        let bvh = Bvh::from_bytes(file).map_err(in_geometry)?;
        let inputs = input_count(&bvh) as u64;
        if inputs != count {
            return Err(LoadError::GeometryLength {
                geometry: k,
                triangles: count,
                inputs,
            });
        }
        Ok(match kind {
            KIND_TRIANGLES => Geometry::Triangles(bvh, tris),
            _ => Geometry::Prims(bvh, tris),
        })
    }

    /// Geometry `k`, a moving mesh of `count` triangles (`n` bytes a step), after its head:
    /// its step count, then each step's triangle count and triangles, checked as
    /// [`super::WorldBuilder::add_moving_triangles`] checks them; then its trees, built.
    fn moving(&mut self, k: usize, count: u64, n: u64) -> Result<Geometry, LoadError> {
        let steps_n =
            u64::from_le_bytes(self.take(8, "moving mesh step count")?.try_into().unwrap());
        let steps_error = |step, why| LoadError::World(WorldError::steps(k, (step, why)));
        if steps_n < 2 {
            return Err(steps_error(None, "fewer than two time steps"));
        }
        // Every step takes at least its head: the count is bounded by the bytes left.
        let left = (self.bytes.len() - self.at) as u64;
        if steps_n > left / STEP_HEAD {
            return Err(LoadError::Truncated {
                section: "moving mesh steps",
                need: (self.at as u64).saturating_add(steps_n.saturating_mul(STEP_HEAD)),
                have: self.bytes.len() as u64,
            });
        }
        let mut steps = Vec::with_capacity(steps_n as usize);
        for j in 0..steps_n as usize {
            let head = self.take(STEP_HEAD, "moving mesh step head")?;
            if u64::from_le_bytes(head.try_into().unwrap()) != count {
                return Err(steps_error(
                    Some(j),
                    "a different number of triangles than the mesh",
                ));
            }
            steps.push(read_triangles(self.take(n, "moving mesh triangles")?));
        }
        check_steps(&steps).map_err(|e| LoadError::World(WorldError::steps(k, e)))?;
        let isa = BuildOptions::default().chosen_isa();
        Ok(Geometry::MovingTriangles(MovingTriangles::new(steps, isa)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Layout;
    use crate::testing::soup;
    use crate::traverse::RayQuery;
    use crate::{InstanceId, Ray};
    use glam::{Quat, Vec3, Vec3A};

    /// Three geometries (one with its own layout), instances moved, scaled, masked, one
    /// removed by an edit.
    fn edited_world() -> World {
        let mut b = World::builder();
        let a = b.add_triangles(soup(300, 1));
        let c = b.add_triangles(soup(200, 2));
        let d = b.add_prims(soup(100, 3));
        b.set_options(c, &BuildOptions::default().layout(Layout::Bvh4Quant))
            .unwrap();
        for i in 0..30 {
            let g = [a, c, d][i % 3];
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.5 + (i % 4) as f32 * 0.25),
                Quat::from_rotation_y(i as f32 * 0.3),
                Vec3::new((i % 6) as f32 * 3.0, (i / 6) as f32 * 3.0, 0.0),
            );
            b.add_instance(
                Instance::of(g)
                    .transform(m)
                    .mask(1 << (i % 3))
                    .user_id(i as u32),
            );
        }
        let mut world = b.build(&BuildOptions::default()).unwrap();
        let mut edit = world.edit();
        edit.remove_instance(InstanceId(4)).unwrap();
        edit.commit();
        world
    }

    fn rays(world: &World, n: usize) -> Vec<Ray> {
        let b = world.bounds();
        let mut rng = crate::rng::Rng::new(9);
        (0..n)
            .map(|i| {
                let from = rng.in_box(b.min, b.max);
                let to = rng.in_box(b.min, b.max);
                Ray::new(from, to - from).with_mask([u32::MAX, 1, 6][i % 3])
            })
            .collect()
    }

    #[test]
    fn a_loaded_world_answers_as_the_saved_one() {
        let world = edited_world();
        let bytes = world.to_bytes();
        let loaded = World::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.instances(), world.instances());
        assert_eq!(loaded.to_bytes(), bytes);
        let rays = rays(&world, 4000);
        let mut hits = 0;
        for r in &rays {
            let want = world.closest_hit(r);
            hits += usize::from(want.is_some());
            assert_eq!(loaded.closest_hit(r), want, "{r:?}");
            assert_eq!(loaded.any_hit(r), world.any_hit(r), "{r:?}");
            assert_ne!(want.map(|h| h.instance), Some(InstanceId(4)));
        }
        assert!(hits > 400, "{hits} hits: the rays must meet the scene");
        let (mut a, mut b) = (vec![None; rays.len()], vec![None; rays.len()]);
        world.closest_hit_packet(&rays, &mut a);
        loaded.closest_hit_packet(&rays, &mut b);
        assert_eq!(a, b);
        for r in rays.iter().take(200) {
            let p = r.origin;
            assert_eq!(loaded.closest_point(p, 2.0), world.closest_point(p, 2.0));
        }
    }

    #[test]
    fn every_cut_and_every_changed_instance_is_an_error() {
        let world = edited_world();
        let bytes = world.to_bytes();
        for n in (0..bytes.len()).step_by(97) {
            assert!(World::from_bytes(&bytes[..n]).is_err(), "{n} bytes");
        }
        // Changed and resealed (a checksum a hostile writer computes): the checks after it
        // must refuse what is wrong.
        let reseal = |mut b: Vec<u8>| {
            let end = b.len() - 8;
            let sum = checksum(&b[..end]);
            b[end..].copy_from_slice(&sum.to_le_bytes());
            b
        };
        let end = bytes.len() - 8;
        let first = end - 30 * INSTANCE_BYTES;
        let mut b = bytes.clone();
        b[first..first + 4].copy_from_slice(&3u32.to_le_bytes()); // geometry 3 of 3
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::World(super::super::WorldError::Geometry {
                instance: 0,
                ..
            }))
        ));
        let mut b = bytes.clone();
        b[first + 16..first + 20].copy_from_slice(&0f32.to_le_bytes()); // x axis' x
        b[first + 20..first + 24].copy_from_slice(&0f32.to_le_bytes());
        b[first + 24..first + 28].copy_from_slice(&0f32.to_le_bytes());
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::World(super::super::WorldError::Transform {
                instance: 0,
                ..
            }))
        ));
        let mut b = bytes.clone();
        b[first + 12] = 4; // flags: neither removed nor moving
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::BadHeader {
                field: "instance flags",
                value: 4
            })
        ));
        let mut b = bytes.clone();
        b[first + 12] = 2; // moving, but no motion follows
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::Truncated {
                section: "motion head",
                ..
            })
        ));
        let mut b = bytes.clone();
        b[HEAD + 8] += 1; // geometry 0's triangle count, one more than its BVH's
        assert!(World::from_bytes(&reseal(b)).is_err());
        let mut b = bytes.clone();
        b.splice(end..end, [0u8; 8]);
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::TrailingBytes { extra: 8 })
        ));
        let mut b = bytes.clone();
        b[24..32].copy_from_slice(&u64::MAX.to_le_bytes()); // instances
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::LengthOverflow {
                section: "instances"
            })
        ));
        let mut b = bytes;
        b[HEAD + GEOMETRY_HEAD + 300 * TRIANGLE_BYTES] ^= 0x20; // geometry 0's BVH's magic
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::InGeometry { geometry: 0, .. })
        ));
    }

    /// A world of a moving mesh of three steps (geometry 0, `MOVING_TRIS` triangles), a
    /// static one, a moving mesh of two steps, and instances of each, one moving.
    const MOVING_TRIS: usize = 4;

    fn moving_world() -> World {
        let mut b = World::builder();
        let steps: Vec<Vec<Triangle>> = (0..3).map(|j| soup(MOVING_TRIS, 10 + j)).collect();
        let m = b.add_moving_triangles(steps).unwrap();
        let s = b.add_triangles(soup(20, 4));
        let two = b
            .add_moving_triangles(vec![soup(7, 5), soup(7, 6)])
            .unwrap();
        b.add_instance(Instance::of(m));
        b.add_instance(Instance::of(s).transform(Affine3A::from_translation(Vec3::X)));
        b.add_moving_instance(
            Instance::of(two),
            Motion::linear(vec![
                Affine3A::IDENTITY,
                Affine3A::from_translation(Vec3::Y),
            ]),
        );
        b.add_instance(Instance::of(m).transform(Affine3A::from_rotation_z(0.5)));
        b.build(&BuildOptions::default()).unwrap()
    }

    fn reseal(mut b: Vec<u8>) -> Vec<u8> {
        let end = b.len() - 8;
        let sum = checksum(&b[..end]);
        b[end..].copy_from_slice(&sum.to_le_bytes());
        b
    }

    #[test]
    fn a_world_without_moving_meshes_is_version_1_and_with_one_version_2() {
        assert_eq!(edited_world().to_bytes()[8..12], 1u32.to_le_bytes());
        let world = moving_world();
        let bytes = world.to_bytes();
        assert_eq!(bytes[8..12], 2u32.to_le_bytes());
        let loaded = World::from_bytes(&bytes).unwrap();
        assert_eq!(loaded.to_bytes(), bytes);
        let Geometry::MovingTriangles(m) = &loaded.geometries()[0] else {
            panic!("geometry 0 is a moving mesh")
        };
        let Geometry::MovingTriangles(want) = &world.geometries()[0] else {
            unreachable!()
        };
        assert_eq!(m.steps(), want.steps());
        let mut rng = crate::rng::Rng::new(3);
        let b = world.bounds();
        for _ in 0..2000 {
            let from = rng.in_box(b.min, b.max);
            let to = rng.in_box(b.min, b.max);
            let time = rng.in_box(Vec3A::ZERO, Vec3A::ONE).x;
            let r = Ray::new(from, to - from).with_time(time);
            assert_eq!(loaded.closest_hit(&r), world.closest_hit(&r), "{r:?}");
        }
        // A newer version than this quiver reads.
        let mut b = bytes.clone();
        b[8..12].copy_from_slice(&3u32.to_le_bytes());
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::UnsupportedVersion {
                found: 3,
                supported: 2
            })
        ));
        // Version 1 holds no moving mesh.
        let mut b = bytes;
        b[8..12].copy_from_slice(&1u32.to_le_bytes());
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::BadHeader {
                field: "geometry kind",
                value: 2
            })
        ));
    }

    #[test]
    fn every_cut_and_every_bad_field_of_a_moving_mesh_is_an_error() {
        let bytes = moving_world().to_bytes();
        for n in 0..bytes.len() {
            assert!(World::from_bytes(&bytes[..n]).is_err(), "{n} bytes");
            // Cut and resealed: the lengths must still refuse it.
            if n >= HEAD + 16 {
                let mut b = bytes[..n - 8].to_vec();
                b.extend_from_slice(&[0; 8]);
                assert!(World::from_bytes(&reseal(b)).is_err(), "{n} bytes resealed");
            }
        }
        // Geometry 0: kind at 32, count at 40, step count at 48, step j's count at
        // 56 + j * (8 + 36 * MOVING_TRIS), its triangles after it.
        let (kind, count, steps) = (HEAD, HEAD + 8, HEAD + 16);
        let step = |j: usize| HEAD + 24 + j * (8 + TRIANGLE_BYTES * MOVING_TRIS);
        let set = |at: usize, v: u64| {
            let mut b = bytes.clone();
            b[at..at + 8].copy_from_slice(&v.to_le_bytes());
            World::from_bytes(&reseal(b))
        };
        let steps_error = |r: Result<World, LoadError>| match r {
            Err(LoadError::World(WorldError::Steps {
                geometry: 0,
                step,
                why,
            })) => (step, why),
            other => panic!("{other:?}"),
        };
        assert_eq!(
            steps_error(set(steps, 1)),
            (None, "fewer than two time steps")
        );
        assert_eq!(
            steps_error(set(steps, 0)),
            (None, "fewer than two time steps")
        );
        // One more reads the next geometry's head as a step: its count is not the mesh's.
        assert!(set(steps, 4).is_err());
        for v in [1 << 20, u64::MAX / 8, u64::MAX] {
            assert!(
                matches!(set(steps, v), Err(LoadError::Truncated { .. })),
                "{v} steps"
            );
        }
        for v in [0, 3, 5, u64::MAX] {
            assert_eq!(
                steps_error(set(step(1), v)),
                (Some(1), "a different number of triangles than the mesh"),
                "{v} triangles"
            );
        }
        assert!(matches!(
            set(count, u64::MAX),
            Err(LoadError::LengthOverflow {
                section: "geometry triangles"
            })
        ));
        for v in [0, 5, 1 << 40] {
            assert!(set(count, v).is_err(), "{v} triangles");
        }
        let mut b = bytes.clone();
        b[kind + 4] = 1; // reserved
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::BadHeader {
                field: "geometry reserved",
                ..
            })
        ));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let mut b = bytes.clone();
            let at = step(2) + 8 + TRIANGLE_BYTES + 4; // step 2, triangle 1, v0.y
            b[at..at + 4].copy_from_slice(&bad.to_le_bytes());
            assert_eq!(
                steps_error(World::from_bytes(&reseal(b))),
                (Some(2), "a vertex that is not finite")
            );
        }
        // Every byte of the mesh's fields set to each of a few values, resealed: an error
        // or a world, never a panic.
        for at in HEAD..step(0) + 8 {
            for v in [0u8, 1, 2, 3, 0x7f, 0x80, 0xff] {
                let mut b = bytes.clone();
                b[at] = v;
                let _ = World::from_bytes(&reseal(b));
            }
        }
        // Any byte flipped without resealing: the checksum.
        for at in (HEAD..bytes.len() - 8).step_by(7) {
            let mut b = bytes.clone();
            b[at] ^= 0x10;
            assert!(matches!(
                World::from_bytes(&b),
                Err(LoadError::Checksum { .. })
            ));
        }
    }
}
