//! The S-triangle machinery's options (a leaf: the technique list's options struct gathers them
//! without importing the technique).

/// How the opacity texture is read at a crossing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Filter {
    /// Nearest texel (the contract's default and the reference's rule:
    /// `Texture::lookup_scalar`).
    #[default]
    Nearest,
    /// Bilinear between the four nearest texel centres, repeating
    /// (`bilinear_scalar`).
    Bilinear,
}

/// Soft textured shadow volumes' command-line option.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::Args)]
pub struct StsvOptions {
    /// Opacity textures of S-triangles (soft textured shadow volumes):
    /// `nearest` texel (the contract's rule) or `bilinear`.
    #[arg(long, value_enum, default_value_t = Filter::Nearest)]
    pub opacity_filter: Filter,
}
