//! What each collider is, stored in its `user_data`, so that sensors and monitors can tell the
//! robot, the parts, the bottles and the scenery apart.

/// What a collider is, stored in its `user_data`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Tag {
    /// Static scenery: floor, pedestal, conveyor frame.
    Scenery = 1,
    /// The belt's top.
    Belt = 2,
    /// The photo-eye's beam.
    PhotoEye = 3,
    /// The trial's axle part.
    Part = 4,
    /// The plastic bottle.
    Bottle = 5,
    /// A bin's floor or wall.
    Bin = 6,
    /// A robot link.
    Robot = 7,
}

impl Tag {
    /// The tag as stored in a collider's or body's `user_data`.
    pub const fn bits(self) -> u128 {
        self as u128
    }
}
