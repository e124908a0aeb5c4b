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

/// Which colliders may pair: the broad phase skips a pair whose groups exclude each other, so
/// the narrow phase and the solver never see it.
pub mod groups {
    use rapier3d::prelude::{Group, InteractionGroups, InteractionTestMode};

    /// Scenery the arm cannot reach (floor, pedestal, the stands under the bins).
    const OUT_OF_REACH: Group = Group::GROUP_1;
    /// The arm's links and the gripper.
    const ROBOT: Group = Group::GROUP_2;
    /// The photo-eye's beam.
    const EYE: Group = Group::GROUP_3;
    /// What the photo-eye is there to see: parts and bottles.
    const ITEM: Group = Group::GROUP_4;

    /// Scenery below and beside the arm that no link can reach: it pairs with parts and bottles
    /// (which fall on it) but not with the robot, whose links otherwise sat within the contact
    /// prediction distance of the pedestal at every step.
    pub const fn out_of_reach() -> InteractionGroups {
        InteractionGroups::new(
            OUT_OF_REACH,
            Group::ALL.difference(ROBOT),
            InteractionTestMode::And,
        )
    }

    /// The robot: everything but the out-of-reach scenery, the photo-eye (an arm passing
    /// through the beam is not a part arriving) and itself (its links overlap at their joints by
    /// design, and the planner keeps it clear of itself).
    pub const fn robot() -> InteractionGroups {
        InteractionGroups::new(
            ROBOT,
            Group::ALL
                .difference(OUT_OF_REACH)
                .difference(EYE)
                .difference(ROBOT),
            InteractionTestMode::And,
        )
    }

    /// The photo-eye's sensor: parts and bottles only.
    pub const fn photo_eye() -> InteractionGroups {
        InteractionGroups::new(EYE, ITEM, InteractionTestMode::And)
    }
}
