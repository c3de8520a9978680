//! quiver-lab: quiver's harness, apart from the library an embedder uses. Deterministic ray
//! sets ([`rays`]), parallel tracing and interleaved median timing ([`measure`]), the
//! accuracy study ([`accuracy`]), the checks the fuzz targets run ([`checks`]) and quiver's
//! data in obvhs's terms ([`obvhs_bridge`]). The integration tests (`tests/suite`) and the
//! criterion benches (`benches/`) live in this crate.

#![warn(missing_docs)]

pub mod accuracy;
pub mod checks;
pub mod measure;
pub mod obvhs_bridge;
pub mod rays;
