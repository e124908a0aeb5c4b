//! Surface materials of the cell's bodies, chosen to look like the real things under the camera.

/// How a surface reflects light: diffuse albedo, a specular lobe, a grazing-angle sheen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Diffuse albedo, linear RGB in [0, 1].
    pub albedo: [f32; 3],
    /// Specular reflectance.
    pub specular: f32,
    /// Blinn-Phong exponent of the specular lobe.
    pub shininess: f32,
    /// Extra brightness at grazing view angles (thin translucent plastic).
    pub sheen: f32,
    /// Whether oil stains and dirt drawn for the image can land on this surface.
    pub stainable: bool,
}

impl Material {
    /// The machined end face of an axle part: bright, finely turned steel.
    pub const END_FACE: Self = Self {
        albedo: [0.72, 0.72, 0.70],
        specular: 0.25,
        shininess: 24.0,
        sheen: 0.0,
        stainable: true,
    };
    /// The inside of a bore: in its own shadow, it looks nearly black from above.
    pub const BORE: Self = Self {
        albedo: [0.035, 0.035, 0.035],
        specular: 0.0,
        shininess: 1.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The turned outside of a part.
    pub const PART_WALL: Self = Self {
        albedo: [0.35, 0.35, 0.36],
        specular: 0.3,
        shininess: 16.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The conveyor's rubber belt: dark and matte.
    pub const BELT: Self = Self {
        albedo: [0.055, 0.058, 0.062],
        specular: 0.02,
        shininess: 4.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The plastic bottle's body: pale, bluish, with a bright rim at grazing angles.
    pub const BOTTLE: Self = Self {
        albedo: [0.50, 0.58, 0.64],
        specular: 0.35,
        shininess: 60.0,
        sheen: 0.45,
        stainable: false,
    };
    /// The bottle's cap: dark blue plastic.
    pub const BOTTLE_CAP: Self = Self {
        albedo: [0.04, 0.07, 0.22],
        specular: 0.2,
        shininess: 30.0,
        sheen: 0.0,
        stainable: false,
    };
    /// Painted steel of the conveyor's frame and rails.
    pub const FRAME: Self = Self {
        albedo: [0.30, 0.32, 0.34],
        specular: 0.15,
        shininess: 12.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The floor: grey concrete.
    pub const FLOOR: Self = Self {
        albedo: [0.32, 0.31, 0.29],
        specular: 0.0,
        shininess: 1.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The robot's white housings.
    pub const ROBOT: Self = Self {
        albedo: [0.78, 0.79, 0.80],
        specular: 0.2,
        shininess: 20.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The gripper's anodised housing and fingers.
    pub const GRIPPER: Self = Self {
        albedo: [0.12, 0.12, 0.13],
        specular: 0.25,
        shininess: 20.0,
        sheen: 0.0,
        stainable: false,
    };
    /// The plastic bins.
    pub const BIN: Self = Self {
        albedo: [0.10, 0.25, 0.55],
        specular: 0.1,
        shininess: 10.0,
        sheen: 0.0,
        stainable: false,
    };
}
