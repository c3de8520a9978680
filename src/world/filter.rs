//! [`GeometryFilter`]: a geometry's own hit filter (an alpha test on foliage cards), asked
//! only about that geometry's candidates, after the query's filter.

use super::WorldHit;
use crate::traverse::Filter;
use std::fmt;
use std::sync::Arc;

/// A geometry's own filter: whether to keep a candidate hit of the geometry, given as the
/// world hit it would be (instance, geometry, primitive, `t`, `u`, `v`). Set by
/// [`WorldBuilder::set_filter`](super::WorldBuilder::set_filter) or
/// [`WorldEdit::set_filter`](super::WorldEdit::set_filter); shared by every instance of the
/// geometry and every thread, so it is `Fn + Send + Sync`.
///
/// A geometry without one costs its queries nothing more; one with a filter is searched
/// through its own query (not inlined in the world's walk), and in packets ray by ray.
#[derive(Clone)]
pub struct GeometryFilter(pub(super) Arc<dyn Fn(&WorldHit) -> bool + Send + Sync>);

impl fmt::Debug for GeometryFilter {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("GeometryFilter")
    }
}

impl GeometryFilter {
    /// `keep` as a geometry filter.
    pub fn new(keep: impl Fn(&WorldHit) -> bool + Send + Sync + 'static) -> GeometryFilter {
        GeometryFilter(Arc::new(keep))
    }
}

/// The query's filter, then the geometry's own.
pub(super) struct Both<'a, F> {
    pub(super) query: &'a mut F,
    pub(super) own: &'a GeometryFilter,
}

impl<F: Filter<WorldHit>> Filter<WorldHit> for Both<'_, F> {
    #[inline(always)]
    fn accept(&mut self, h: &WorldHit) -> bool {
        self.query.accept(h) && (self.own.0)(h)
    }
}
