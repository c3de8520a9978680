//! The caller's buffers read into Rust: vertex and index buffers with strides (copied, each
//! element read unaligned, so padding between elements is never touched), and arrays of rays
//! and answers as slices. Every size is checked for overflow before a pointer is formed.

use crate::error::{Failure, QvStatus};
use quiver_rt::{MeshError, Positions};
use std::mem::MaybeUninit;

/// The bytes `count` elements of `elem` bytes, `stride` bytes apart, span; refused (naming
/// `name`) when that overflows what one allocation can hold (`isize::MAX` bytes).
fn span(name: &str, count: usize, stride: usize, elem: usize) -> Result<usize, Failure> {
    if count == 0 {
        return Ok(0);
    }
    (count - 1)
        .checked_mul(stride)
        .and_then(|s| s.checked_add(elem))
        .filter(|&s| s <= isize::MAX as usize)
        .ok_or_else(|| {
            Failure::new(
                QvStatus::InvalidArgument,
                format!("{name}: {count} elements {stride} bytes apart overflow the address space"),
            )
        })
}

/// `ptr` checked for a buffer of `count` elements: NULL is allowed only when there are none.
fn check_pointer<T>(ptr: *const T, count: usize, name: &str) -> Result<(), Failure> {
    match ptr.is_null() && count > 0 {
        true => Err(Failure::null(name)),
        false => Ok(()),
    }
}

/// Copies `count` vertex positions, vertex `i`'s three `f32` at byte `i * stride` of
/// `vertices`; refuses a stride shorter than a position, and a non-finite coordinate (naming
/// the vertex).
///
/// # Safety
/// When `count > 0`, `vertices` points to a buffer readable for `(count - 1) * stride + 12`
/// bytes (any alignment), whose position bytes are initialised.
pub(crate) unsafe fn read_vertices(
    vertices: *const f32,
    count: usize,
    stride: usize,
) -> Result<Vec<[f32; 3]>, Failure> {
    check_pointer(vertices, count, "vertices")?;
    // The core's own stride rule (a position must fit inside one stride), on no bytes.
    Positions::strided(&[], 0, stride).map_err(|e| bad_mesh("vertex_stride_bytes", e))?;
    span("vertices", count, stride, 12)?;
    let base = vertices.cast::<u8>();
    let mut out = Vec::with_capacity(count);
    for i in 0..count {
        // SAFETY: `i * stride + 12 <= (count - 1) * stride + 12`, which `span` checked does not
        // overflow and which the caller promised is readable from `vertices` (non-NULL, as
        // checked, since count > 0 here); `read_unaligned` needs no alignment.
        let p = unsafe { base.add(i * stride).cast::<[f32; 3]>().read_unaligned() };
        if let Some(axis) = p.iter().position(|c| !c.is_finite()) {
            return Err(Failure::new(
                QvStatus::BadMesh,
                format!(
                    "vertices: vertex {i} has a non-finite coordinate ({} = {})",
                    ["x", "y", "z"][axis],
                    p[axis]
                ),
            ));
        }
        out.push(p);
    }
    Ok(out)
}

/// Copies `count` index triples, triangle `t`'s three `u32` at byte `t * stride` of
/// `indices`, and checks each names one of `vertices` vertices (naming the triangle, corner
/// and index that does not).
///
/// # Safety
/// When `count > 0`, `indices` points to a buffer readable for `(count - 1) * stride + 12`
/// bytes (any alignment), whose index bytes are initialised.
pub(crate) unsafe fn read_indices(
    indices: *const u32,
    count: usize,
    stride: usize,
    vertices: usize,
) -> Result<Vec<[u32; 3]>, Failure> {
    check_pointer(indices, count, "indices")?;
    if stride < 12 {
        return Err(Failure::new(
            QvStatus::BadMesh,
            format!(
                "index_stride_bytes: a stride of {stride} bytes cannot hold a triangle's three \
                 uint32_t (12 bytes)"
            ),
        ));
    }
    if count > u32::MAX as usize {
        let e = MeshError::TooManyTriangles { triangles: count };
        return Err(bad_mesh("triangle_count", e));
    }
    span("indices", count, stride, 12)?;
    let base = indices.cast::<u8>();
    let mut out = Vec::with_capacity(count);
    for triangle in 0..count {
        // SAFETY: as in `read_vertices`: the offset is inside the checked span the caller
        // promised is readable, and the read is unaligned.
        let tri = unsafe {
            base.add(triangle * stride)
                .cast::<[u32; 3]>()
                .read_unaligned()
        };
        if let Some(corner) = tri.iter().position(|&i| i as usize >= vertices) {
            let e = MeshError::IndexOutOfRange {
                triangle,
                corner,
                index: tri[corner],
                vertices,
            };
            return Err(bad_mesh("indices", e));
        }
        out.push(tri);
    }
    Ok(out)
}

/// A mesh error on argument `name`.
pub(crate) fn bad_mesh(name: &str, e: MeshError) -> Failure {
    Failure::new(QvStatus::BadMesh, format!("{name}: {e}"))
}

/// The `n` elements at `ptr` as a slice (empty, whatever `ptr`, when `n` is 0).
///
/// # Safety
/// When `n > 0`, `ptr` points to `n` initialised, properly aligned `T`s that nothing writes
/// while the slice is in use.
pub(crate) unsafe fn input<'a, T>(ptr: *const T, n: usize, name: &str) -> Result<&'a [T], Failure> {
    check_pointer(ptr, n, name)?;
    span(name, n, size_of::<T>(), size_of::<T>())?;
    if n == 0 {
        return Ok(&[]);
    }
    // SAFETY: `ptr` is not NULL (checked), the caller promised `n` initialised aligned
    // elements not written meanwhile, and `n * size_of::<T>()` fits in `isize` (checked).
    Ok(unsafe { std::slice::from_raw_parts(ptr, n) })
}

/// The `n` slots at `ptr` as a slice to write answers into (empty when `n` is 0); the slots
/// need not be initialised.
///
/// # Safety
/// When `n > 0`, `ptr` points to `n` properly aligned `T` slots, writable, that nothing else
/// reads or writes while the slice is in use (in particular, not overlapping an input).
pub(crate) unsafe fn output<'a, T>(
    ptr: *mut T,
    n: usize,
    name: &str,
) -> Result<&'a mut [MaybeUninit<T>], Failure> {
    check_pointer(ptr, n, name)?;
    span(name, n, size_of::<T>(), size_of::<T>())?;
    if n == 0 {
        return Ok(&mut []);
    }
    // SAFETY: `ptr` is not NULL (checked), the caller promised `n` aligned writable slots used
    // by nothing else, the size fits in `isize` (checked), and `MaybeUninit` makes no claim
    // that the slots hold valid values.
    Ok(unsafe { std::slice::from_raw_parts_mut(ptr.cast::<MaybeUninit<T>>(), n) })
}
