//! Saving a [`World`] of triangles and loading it back: [`World::save`], [`World::to_bytes`],
//! [`World::load`], [`World::from_bytes`].
//!
//! The format (`docs/file-format.md` has the byte table): a 32-byte header (magic, format
//! version, endianness marker, geometry and instance counts), then each geometry (its kind,
//! its triangles in input order, then its BVH as one whole BVH file, [`Bvh::save`]'s bytes),
//! then the instances (64 bytes each: geometry, mask, user id, removed flag, transform), then
//! a checksum of everything before it. The top level is not stored: loading builds it again
//! (a few milliseconds per ten thousand instances), from the same instances, as
//! [`super::WorldBuilder::build`] would. Filters are code and are not stored either: set them
//! again after loading ([`super::WorldEdit::set_filter`]).

use super::builder::Placed;
use super::{Geometry, GeometryId, Instance, World};
use crate::bvh::{BuildOptions, Bvh};
use crate::geometry::Triangle;
use crate::save::{
    checksum, input_count, read_triangles, saved_len, triangle_bytes, Hashing, ENDIAN,
    TRIANGLE_BYTES,
};
use crate::{LoadError, FORMAT_VERSION};
use glam::Affine3A;
use std::io::{self, Read, Write};

/// The first eight bytes of a world file (a BVH file's are `QUIVBVH\x1a`).
const MAGIC: [u8; 8] = *b"QUIVWLD\x1a";

/// Bytes of the header.
const HEAD: usize = 32;

/// Bytes before a geometry's triangles: its kind, four reserved zero bytes, its count.
const GEOMETRY_HEAD: usize = 16;

/// Bytes of one instance: geometry, mask, user id, removed flag (u32 each), then the
/// transform's twelve f32 (the columns of the linear part, then the translation).
const INSTANCE_BYTES: usize = 64;

/// A geometry's kind in the file.
const KIND_TRIANGLES: u32 = 0;
const KIND_PRIMS: u32 = 1;

impl World {
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
    /// # Errors
    /// What `w` returns.
    pub fn save<W: Write + ?Sized>(&self, w: &mut W) -> io::Result<()> {
        let mut out = Hashing::new(w);
        let mut head = [0u8; HEAD];
        head[..8].copy_from_slice(&MAGIC);
        head[8..12].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        head[12..16].copy_from_slice(&ENDIAN.to_ne_bytes());
        head[16..24].copy_from_slice(&(self.geometries.len() as u64).to_le_bytes());
        head[24..32].copy_from_slice(&(self.instances.len() as u64).to_le_bytes());
        out.put(&head)?;
        for g in &self.geometries {
            let (kind, bvh, tris) = match g {
                Geometry::Triangles(b, t) => (KIND_TRIANGLES, b, t),
                Geometry::Prims(b, t) => (KIND_PRIMS, b, t),
            };
            let mut gh = [0u8; GEOMETRY_HEAD];
            gh[..4].copy_from_slice(&kind.to_le_bytes());
            gh[8..].copy_from_slice(&(tris.len() as u64).to_le_bytes());
            out.put(&gh)?;
            let mut bytes = Vec::with_capacity(tris.len().min(1 << 16) * TRIANGLE_BYTES);
            for chunk in tris.chunks(1 << 16) {
                bytes.clear();
                chunk.iter().for_each(|t| triangle_bytes(t, &mut bytes));
                out.put(&bytes)?;
            }
            bvh.save(&mut out)?;
        }
        for (i, inst) in self.instances.iter().enumerate() {
            let removed = self.removed.get(i) == Some(&true);
            let mut b = [0u8; INSTANCE_BYTES];
            let words = [inst.geometry.0, inst.mask, inst.user_id, u32::from(removed)];
            let floats = inst.transform.to_cols_array();
            for (slot, w) in b.chunks_exact_mut(4).zip(
                words
                    .iter()
                    .map(|w| w.to_le_bytes())
                    .chain(floats.iter().map(|f| f.to_le_bytes())),
            ) {
                slot.copy_from_slice(&w);
            }
            out.put(&b)?;
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
        if bytes.len() >= MAGIC.len() && bytes[..MAGIC.len()] != MAGIC {
            return Err(LoadError::BadMagic);
        }
        if bytes.len() < HEAD + 8 {
            return Err(LoadError::Truncated {
                section: "header",
                need: (HEAD + 8) as u64,
                have,
            });
        }
        let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
        let long = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        let version = word(8);
        if version == 0 || version > FORMAT_VERSION {
            return Err(LoadError::UnsupportedVersion {
                found: version,
                supported: FORMAT_VERSION,
            });
        }
        let endian = u32::from_ne_bytes(bytes[12..16].try_into().unwrap());
        if endian != ENDIAN {
            return Err(match endian.swap_bytes() == ENDIAN {
                true => LoadError::WrongEndianness,
                false => LoadError::BadHeader {
                    field: "endianness",
                    value: endian.into(),
                },
            });
        }
        let end = bytes.len() - 8;
        let (stored, computed) = (long(end), checksum(&bytes[..end]));
        if stored != computed {
            return Err(LoadError::Checksum { stored, computed });
        }
        let (geometries_n, instances_n) = (long(16), long(24));
        let mut at = Cursor {
            bytes: &bytes[..end],
            at: HEAD,
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
        for b in table.chunks_exact(INSTANCE_BYTES) {
            let w: Vec<u32> = b
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
                .collect();
            let transform =
                Affine3A::from_cols_array(&std::array::from_fn(|i| f32::from_bits(w[4 + i])));
            instances.push(Instance {
                geometry: GeometryId(w[0]),
                transform,
                mask: w[1],
                user_id: w[2],
            });
            removed.push(match w[3] {
                0 => false,
                1 => true,
                value => {
                    return Err(LoadError::BadHeader {
                        field: "instance removed flag",
                        value: value.into(),
                    })
                }
            });
        }
        if at.at != end {
            return Err(LoadError::TrailingBytes {
                extra: (end - at.at) as u64,
            });
        }
        if !removed.contains(&true) {
            removed.clear();
        }
        let placed = Placed {
            geometries,
            instances,
            removed,
        };
        placed
            .world(&BuildOptions::default())
            .map_err(LoadError::World)
    }
}

/// Reading a world file's body front to back, every length checked against what is left.
struct Cursor<'a> {
    bytes: &'a [u8],
    at: usize,
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

    /// Geometry `k`: its head, its triangles, its BVH.
    fn geometry(&mut self, k: usize) -> Result<Geometry, LoadError> {
        let head = self.take(GEOMETRY_HEAD as u64, "geometry head")?;
        let kind = u32::from_le_bytes(head[..4].try_into().unwrap());
        let reserved = u32::from_le_bytes(head[4..8].try_into().unwrap());
        let count = u64::from_le_bytes(head[8..].try_into().unwrap());
        if kind > KIND_PRIMS {
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::layout::Layout;
    use crate::testing::soup;
    use crate::traverse::RayQuery;
    use crate::{InstanceId, Ray};
    use glam::{Quat, Vec3};

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
        b[first + 12] = 2; // removed flag
        assert!(matches!(
            World::from_bytes(&reseal(b)),
            Err(LoadError::BadHeader {
                field: "instance removed flag",
                value: 2
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
}
