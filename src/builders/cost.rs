//! How a candidate split is scored: [`CostModel`] (the SAH and Moulin and Dutré's
//! ray-termination variants), and the split-or-leaf test every top-down builder makes.

use super::config::by_name;
use super::BuildConfig;
use std::fmt;

/// The cost a builder minimises when it picks a split, for both builders.
///
/// The SAH assumes rays that never stop. Moulin and Dutré ("On the use of local ray
/// termination for efficiently constructing qualitative BSPs, BIHs and (S)BVHs") adapt it to
/// rays that end at their first hit. Both variants here use their *average projected surface
/// area* (APSA) approximation of the chance that a ray crossing a child's box hits one of its
/// primitives: `H = min(ΣSA(primitives) / SA(box), 1)` (their equation 5.19), which needs each
/// primitive's surface area ([`crate::Primitive::surface_area`]).
///
/// ```
/// use quiver_rt::builders::CostModel;
/// assert_eq!(CostModel::default(), CostModel::Sah);
/// assert_eq!("rtsah".parse::<CostModel>(), Ok(CostModel::Rtsah));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum CostModel {
    /// `c_T + c_I·(p_L·n_L + p_R·n_R)` with `p = SA(child) / SA(parent)`.
    #[default]
    Sah,
    /// The ray termination SAH (their equation 3.4) with local ray termination: of the rays
    /// that pierce both children, half meet the left one first (`p_fL = p_fR = 1/2`), and
    /// those stopped there never test the right one's primitives (probability `H_L`, APSA).
    /// The share of rays piercing both children, `p_L↔R`, is taken as
    /// `max(0, p_L + p_R - 1)`: exact when the children tile the parent (a BSP split), a
    /// lower bound for a BVH's children (their grid-transport estimate is not built), so
    /// splits whose children's areas do not sum past the parent's are scored as by the SAH.
    /// Also decides when a node becomes a leaf.
    Rtsah,
    /// The shadow ray distribution heuristic (their equation 3.23), a gain to maximise for
    /// any-hit rays: `max(p_L·H_L·(c + p_R·n_R), p_R·H_R·(c + p_L·n_L))` (the tests saved when
    /// the child visited first stops the ray), with `c = c_T / c_I` as the box test's cost
    /// relative to a primitive's. Leaves are decided by the SAH of the chosen split. quiver's
    /// kernels keep their own child order (nearest first, or slot order for any hit), so
    /// the traversal-order half of SRDH is not used.
    Srdh,
}

impl CostModel {
    /// Every cost model, in the order reports list them.
    pub const ALL: [CostModel; 3] = [CostModel::Sah, CostModel::Rtsah, CostModel::Srdh];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            CostModel::Sah => "sah",
            CostModel::Rtsah => "rtsah",
            CostModel::Srdh => "srdh",
        }
    }
}

impl fmt::Display for CostModel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for CostModel {
    type Err = String;

    /// A cost model by its [`CostModel::name`]; the error lists the names.
    fn from_str(s: &str) -> Result<Self, String> {
        by_name(s, &CostModel::ALL, CostModel::name, "cost model")
    }
}

/// One side of a candidate split as the cost models see it.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Side {
    /// Half the surface area of the side's box.
    pub half_area: f32,
    /// Primitives on the side.
    pub count: usize,
    /// Σ surface area of those primitives.
    pub prim_area: f32,
}

impl Side {
    /// APSA: the chance that a ray crossing the box hits one of the primitives.
    fn hit_chance(&self) -> f32 {
        if self.half_area > 0.0 {
            (self.prim_area / (2.0 * self.half_area)).min(1.0)
        } else if self.prim_area > 0.0 {
            1.0
        } else {
            0.0
        }
    }
}

/// A candidate split's score under `config.cost_model`, lower is better, and its weighted
/// child cost for the leaf test ([`split_beats_leaf`]): `(score, weighted)`. For the SAH
/// both are `Σ half area · tests` ([`BuildConfig::tests`]: the count, or the leaf's groups).
pub(crate) fn model_score(
    config: &BuildConfig,
    parent_area: f32,
    l: &Side,
    r: &Side,
) -> (f32, f32) {
    let (nl, nr) = (config.tests(l.count), config.tests(r.count));
    let sah = l.half_area * nl + r.half_area * nr;
    match config.cost_model {
        CostModel::Sah => (sah, sah),
        CostModel::Rtsah => {
            // p_L↔R · A_P, and the tests each side's primitives are spared by the other.
            let both = (l.half_area + r.half_area - parent_area).max(0.0);
            let spared = 0.5 * both * (r.hit_chance() * nl + l.hit_chance() * nr);
            (sah - spared, sah - spared)
        }
        CostModel::Srdh => {
            let c = if config.intersection_cost > 0.0 {
                config.traversal_cost / config.intersection_cost
            } else {
                1.0
            };
            let p = |s: &Side| {
                if parent_area > 0.0 {
                    s.half_area / parent_area
                } else {
                    1.0
                }
            };
            let gain = (p(l) * l.hit_chance() * (c + p(r) * nr))
                .max(p(r) * r.hit_chance() * (c + p(l) * nl));
            (-gain, sah)
        }
    }
}

/// SAH cost of splitting a node of area `parent_area` into children with area·count products
/// summing to `weighted`, compared with making it a leaf of `n` primitives.
pub(crate) fn split_beats_leaf(
    config: &BuildConfig,
    parent_area: f32,
    weighted: f32,
    n: usize,
) -> bool {
    split_cost(config, parent_area, weighted, n) < config.intersection_cost * config.tests(n)
}

/// `c_T + c_I * weighted / A_P`; a zero-area parent (every primitive at one point) makes each
/// child as likely to be hit as the parent.
fn split_cost(config: &BuildConfig, parent_area: f32, weighted: f32, n: usize) -> f32 {
    let ratio = if parent_area > 0.0 {
        weighted / parent_area
    } else {
        config.tests(n)
    };
    config.traversal_cost + config.intersection_cost * ratio
}
