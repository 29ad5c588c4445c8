//! `I/N`: share `I` (1-based) of `N`, as `compare --shard` and
//! `render --tiles` take it. One parser, so both accept the same texts;
//! each caller words its own error.

/// Why a text is not `I/N` with `1 <= I <= N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ShareError {
    /// No `/`.
    NoSlash,
    /// `I` is not a whole number.
    IndexNotNumber,
    /// `N` is not a whole number.
    CountNotNumber,
    /// `N` is 0.
    NoShares,
    /// `I` is outside `1..=N`.
    IndexOutOfRange {
        /// `N`.
        count: u32,
    },
}

/// Parses `I/N` (spaces around either number allowed) as `(I, N)` with
/// `1 <= I <= N`.
pub fn parse_share(text: &str) -> Result<(u32, u32), ShareError> {
    let (index, count) = text.split_once('/').ok_or(ShareError::NoSlash)?;
    let index: u32 = index
        .trim()
        .parse()
        .map_err(|_| ShareError::IndexNotNumber)?;
    let count: u32 = count
        .trim()
        .parse()
        .map_err(|_| ShareError::CountNotNumber)?;
    if count == 0 {
        return Err(ShareError::NoShares);
    }
    if index == 0 || index > count {
        return Err(ShareError::IndexOutOfRange { count });
    }
    Ok((index, count))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_parse_and_refuse_with_the_reason() {
        assert_eq!(parse_share("2/3"), Ok((2, 3)));
        assert_eq!(parse_share(" 3 / 3 "), Ok((3, 3)));
        assert_eq!(parse_share("3"), Err(ShareError::NoSlash));
        assert_eq!(parse_share("a/3"), Err(ShareError::IndexNotNumber));
        assert_eq!(parse_share("-1/3"), Err(ShareError::IndexNotNumber));
        assert_eq!(parse_share("1/b"), Err(ShareError::CountNotNumber));
        assert_eq!(parse_share("1/0"), Err(ShareError::NoShares));
        assert_eq!(parse_share("0/0"), Err(ShareError::NoShares));
        assert_eq!(
            parse_share("0/3"),
            Err(ShareError::IndexOutOfRange { count: 3 })
        );
        assert_eq!(
            parse_share("4/3"),
            Err(ShareError::IndexOutOfRange { count: 3 })
        );
    }
}
