//! quiver-lab: quiver's harness, apart from the library an embedder uses. Deterministic ray
//! sets ([`rays`]), isotropic random lines and the walk that counts what they pierce
//! ([`lines`]), parallel tracing and interleaved median timing ([`measure`]), the
//! accuracy study ([`accuracy`]), the checks the fuzz targets run ([`checks`]) and quiver's
//! data in obvhs's terms ([`obvhs_bridge`]); with the `embree` feature, Intel Embree 3 as a
//! second comparison engine (`embree`, which links `libembree3`), and with `tinybvh`,
//! tinybvh's `BVH8_CPU` and `BVH4_CPU` as a third (`tinybvh`, over the tinybvh-rs crate). The
//! core's integration tests (`tests/suite`) and criterion benches (`benches/`) use it.

#![warn(missing_docs)]

pub mod accuracy;
pub mod checks;
#[cfg(feature = "embree")]
pub mod embree;
pub mod lines;
pub mod measure;
pub mod obvhs_bridge;
pub mod oracle;
pub mod point_oracle;
pub mod rays;
#[cfg(feature = "tinybvh")]
pub mod tinybvh;
pub mod worlds;
