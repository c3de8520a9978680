//! SPD `tree` (being written).

use crate::scene::Scene;

pub(crate) fn make(size: u32) -> Scene {
    super::placeholder("tree", size)
}
