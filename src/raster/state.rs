//! Fixed-function state of a draw call: depth and stencil tests and their
//! operations, culling.

/// A comparison `fragment OP stored` (depth) or `reference OP stored`
/// (stencil), as in OpenGL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CompareFunc {
    /// Never passes.
    Never,
    /// Passes if the incoming value is less than the stored one.
    Less,
    /// Passes if less or equal.
    LessEqual,
    /// Passes if equal.
    Equal,
    /// Passes if greater or equal.
    GreaterEqual,
    /// Passes if greater.
    Greater,
    /// Passes if not equal.
    NotEqual,
    /// Always passes.
    Always,
}

impl CompareFunc {
    /// Scalar evaluation (the SIMD paths must agree with this).
    #[inline]
    pub fn test<T: PartialOrd>(self, incoming: T, stored: T) -> bool {
        match self {
            CompareFunc::Never => false,
            CompareFunc::Less => incoming < stored,
            CompareFunc::LessEqual => incoming <= stored,
            CompareFunc::Equal => incoming == stored,
            CompareFunc::GreaterEqual => incoming >= stored,
            CompareFunc::Greater => incoming > stored,
            CompareFunc::NotEqual => incoming != stored,
            CompareFunc::Always => true,
        }
    }
}

/// What a stencil operation does to the stored 32-bit signed count.
///
/// The stencil buffer holds `i32` counts, not 8-bit values: increments and
/// decrements do not wrap at 255 (they wrap only at ±2^31, which needs more
/// overlapping volume faces than any scene can hold in memory).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StencilOp {
    /// Leave the value.
    Keep,
    /// Set to 0.
    Zero,
    /// Set to the reference value.
    Replace,
    /// Add one.
    Increment,
    /// Subtract one.
    Decrement,
    /// Bitwise invert.
    Invert,
}

impl StencilOp {
    /// Scalar evaluation (the SIMD paths must agree with this).
    #[inline]
    pub fn apply(self, stored: i32, reference: i32) -> i32 {
        match self {
            StencilOp::Keep => stored,
            StencilOp::Zero => 0,
            StencilOp::Replace => reference,
            StencilOp::Increment => stored.wrapping_add(1),
            StencilOp::Decrement => stored.wrapping_sub(1),
            StencilOp::Invert => !stored,
        }
    }
}

/// Stencil test and operations for one facing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StencilFace {
    /// `reference func stored` must hold for the fragment to pass.
    pub func: CompareFunc,
    /// Applied when the stencil test fails.
    pub stencil_fail: StencilOp,
    /// Applied when the stencil test passes and the depth test fails.
    pub depth_fail: StencilOp,
    /// Applied when both tests pass.
    pub pass: StencilOp,
}

impl StencilFace {
    /// A face that tests nothing and changes nothing.
    pub const KEEP: StencilFace = StencilFace {
        func: CompareFunc::Always,
        stencil_fail: StencilOp::Keep,
        depth_fail: StencilOp::Keep,
        pass: StencilOp::Keep,
    };
}

/// Two-sided stencil state.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StencilState {
    /// For front-facing triangles.
    pub front: StencilFace,
    /// For back-facing triangles.
    pub back: StencilFace,
    /// Reference value for the compare and for `Replace`.
    pub reference: i32,
}

/// Which facing is discarded before rasterization.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CullMode {
    /// Keep both facings.
    None,
    /// Drop front-facing triangles.
    Front,
    /// Drop back-facing triangles.
    Back,
}

/// Everything fixed-function about a draw call.
///
/// Depth convention (see docs/architecture.md): reversed Z with an infinite
/// far plane, `depth = near / w_eye` in (0, 1]; larger is closer, points at
/// infinity have depth 0. The usual "closer wins" test is therefore
/// [`CompareFunc::Greater`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RasterState {
    /// Depth test function (`Always` disables the test).
    pub depth_func: CompareFunc,
    /// Whether passing fragments write their depth.
    pub depth_write: bool,
    /// Stencil test and operations; `None` leaves the stencil untouched.
    pub stencil: Option<StencilState>,
    /// Facing culled before rasterization.
    pub cull: CullMode,
}

impl Default for RasterState {
    /// Closer-wins depth test with writes, no stencil, no culling.
    fn default() -> Self {
        RasterState {
            depth_func: CompareFunc::Greater,
            depth_write: true,
            stencil: None,
            cull: CullMode::None,
        }
    }
}
