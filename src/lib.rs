//! twincell: a physics-simulated digital twin of a robot sorting cell.

pub mod perception;
