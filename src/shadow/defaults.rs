//! The command line's defaults of one group of technique options, so that
//! the library and the CLI can never disagree on them. A leaf: every
//! options file may use it.

/// `T` as clap fills it when none of its arguments is given.
pub(crate) fn clap_defaults<T: clap::Args + clap::FromArgMatches>() -> T {
    let matches = T::augment_args(clap::Command::new("defaults")).get_matches_from(["defaults"]);
    T::from_arg_matches(&matches).expect("every technique option has a default")
}
