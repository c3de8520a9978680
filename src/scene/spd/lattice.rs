//! SPD `lattice` (being written).

use crate::scene::Scene;

pub(crate) fn make(size: u32) -> Scene {
    super::placeholder("lattice", size)
}
