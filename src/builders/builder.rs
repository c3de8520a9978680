//! The builder registry: [`Builder`], every algorithm by name.

use super::config::by_name;
use std::fmt;

/// Which algorithm builds the tree.
///
/// The bottom-up builders (PLOC, AAC, insertion) build down to one primitive per leaf and
/// then collapse every subtree into a leaf where the SAH prefers it and it fits in
/// [`super::BuildConfig::max_leaf_size`] (Bittner et al.'s compaction), so their trees obey the same
/// leaf limit as the top-down ones. Parameters are those of Frantál's Table 8.
///
/// ```
/// use quiver_rt::builders::Builder;
/// assert_eq!(Builder::default(), Builder::Binned);
/// assert_eq!("sweep".parse::<Builder>(), Ok(Builder::Sweep));
/// assert_eq!("ploc10".parse::<Builder>(), Ok(Builder::Ploc10));
/// assert_eq!("sbvh".parse::<Builder>(), Ok(Builder::Sbvh));
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Builder {
    /// Parallel binned SAH (horizontal near the root, vertical below). The default.
    #[default]
    Binned,
    /// Full-sweep SAH: every primitive boundary is a candidate plane. The quality reference.
    Sweep,
    /// The binned tree built to single-primitive leaves, improved by the insertion-based
    /// optimisation ([`super::optimize`]), then compacted into SAH leaves.
    BinnedOpt,
    /// The full-sweep tree, optimised the same way (the thesis's FSWO).
    SweepOpt,
    /// Parallel locally-ordered clustering (Meister and Bittner 2018), search radius 10.
    Ploc10,
    /// PLOC with search radius 25.
    Ploc25,
    /// PLOC with search radius 100.
    Ploc100,
    /// PLOC (radius 10) over extended Morton codes (EMC-64-var, Vinkler et al. 2017).
    Ploc10Emc,
    /// Approximate agglomerative clustering (Gu et al. 2013), fast setting: δ = 4, ε = 0.2.
    AacFast,
    /// AAC, high-quality setting: δ = 20, ε = 0.1.
    AacHq,
    /// AAC-HQ over extended Morton codes.
    AacHqEmc,
    /// Bonsai (Ganestam et al. 2015): spatial-median groups of 512, full-sweep mini trees,
    /// a full-sweep top tree over them; no pruning.
    Bonsai,
    /// BonsaiP: groups of 512, mini trees larger than 0.1 × the mean pruned.
    BonsaiP,
    /// BonsaiP*: groups of 4096, pruning threshold 0.01 × the mean.
    BonsaiP4096,
    /// Insertion-based construction (Bittner et al. 2015): batch 8000, 1% of nodes
    /// optimised per batch, coherence threshold 1.5. Sequential.
    Insertion,
    /// Linear BVH: one Morton-code sort, each node split at its codes' highest differing bit,
    /// leaves by the SAH. The fast preset ([`crate::BuildOptions::fast`]): several times
    /// quicker to build than [`Builder::Binned`], with a costlier tree.
    Lbvh,
    /// Spatial-split BVH (Stich et al. 2009): binned object splits and, where their children
    /// overlap, binned spatial splits that put a primitive in both children, each with the
    /// part of it on its side; at most 1.3 references per primitive. The tree's leaves may
    /// then name a primitive more than once (see [`super::BuildTree`]). Triangles are
    /// clipped exactly when built through [`crate::BuildOptions`]; [`super::build`] clips
    /// the boxes it is given.
    Sbvh,
}

impl Builder {
    /// Every builder, in the order reports list them.
    pub const ALL: [Builder; 17] = [
        Builder::Binned,
        Builder::Sweep,
        Builder::BinnedOpt,
        Builder::SweepOpt,
        Builder::Ploc10,
        Builder::Ploc25,
        Builder::Ploc100,
        Builder::Ploc10Emc,
        Builder::AacFast,
        Builder::AacHq,
        Builder::AacHqEmc,
        Builder::Bonsai,
        Builder::BonsaiP,
        Builder::BonsaiP4096,
        Builder::Insertion,
        Builder::Lbvh,
        Builder::Sbvh,
    ];

    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Builder::Binned => "binned",
            Builder::Sweep => "sweep",
            Builder::BinnedOpt => "binned+opt",
            Builder::SweepOpt => "sweep+opt",
            Builder::Ploc10 => "ploc10",
            Builder::Ploc25 => "ploc25",
            Builder::Ploc100 => "ploc100",
            Builder::Ploc10Emc => "ploc10-emc",
            Builder::AacFast => "aac-fast",
            Builder::AacHq => "aac-hq",
            Builder::AacHqEmc => "aac-hq-emc",
            Builder::Bonsai => "bonsai",
            Builder::BonsaiP => "bonsai-p",
            Builder::BonsaiP4096 => "bonsai-p4096",
            Builder::Insertion => "insertion",
            Builder::Lbvh => "lbvh",
            Builder::Sbvh => "sbvh",
        }
    }
}

impl fmt::Display for Builder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Builder {
    type Err = String;

    /// A builder by its [`Builder::name`]; the error lists the names.
    fn from_str(s: &str) -> Result<Self, String> {
        by_name(s, &Builder::ALL, Builder::name, "builder")
    }
}
