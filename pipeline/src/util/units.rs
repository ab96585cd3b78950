//! Parsing of human units on the command line: durations (`90`, `30s`, `10m`, `2h`) and sizes
//! (`512M`, `8G`, `0` for none).

/// Parses a duration in seconds: a number with an optional `s`, `m` or `h` suffix.
pub fn parse_duration(s: &str) -> Result<f64, String> {
    let units = [('s', 1.0), ('m', 60.0), ('h', 3600.0)];
    let (v, factor) = number_and_unit(s.trim(), &units, |c| c)
        .ok_or_else(|| format!("not a duration: {s:?} (examples: 90, 30s, 10m, 2h)"))?;
    if v.is_nan() || v <= 0.0 || !v.is_finite() {
        return Err(format!("duration must be positive: {s:?}"));
    }
    Ok(v * factor)
}

/// Parses a size in bytes: a number with an optional `K`, `M`, `G` or `T` suffix (powers of
/// 1024); `0` means no limit.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let t = s.trim().trim_end_matches(['B', 'b']).trim_end_matches('i');
    let units =
        [('K', 10), ('M', 20), ('G', 30), ('T', 40)].map(|(c, shift)| (c, (1u64 << shift) as f64));
    let (v, factor) = number_and_unit(t, &units, |c| c.to_ascii_uppercase())
        .ok_or_else(|| format!("not a size: {s:?} (examples: 512M, 8G, 0 for none)"))?;
    if v < 0.0 || !v.is_finite() {
        return Err(format!("size must not be negative: {s:?}"));
    }
    Ok((v * factor) as u64)
}

/// The number in `t` before an optional unit suffix, and the factor of that unit (1 without
/// one): `units` lists each suffix with its factor, matched against `t`'s last character as
/// `fold` turns it. `None` when the number does not parse.
fn number_and_unit(t: &str, units: &[(char, f64)], fold: fn(char) -> char) -> Option<(f64, f64)> {
    let unit = t.chars().last().map(fold);
    let (num, factor) = match units.iter().find(|u| Some(u.0) == unit) {
        Some(&(_, factor)) => (&t[..t.len() - 1], factor),
        None => (t, 1.0),
    };
    Some((num.trim().parse().ok()?, factor))
}

/// Formats seconds as `1h02m`, `3m05s` or `4.2s`.
pub fn format_seconds(s: f64) -> String {
    if !s.is_finite() {
        return "?".into();
    }
    let t = s.round() as u64;
    if t >= 3600 {
        format!("{}h{:02}m", t / 3600, (t % 3600) / 60)
    } else if t >= 60 {
        format!("{}m{:02}s", t / 60, t % 60)
    } else {
        format!("{s:.1}s")
    }
}

/// Formats bytes as the largest whole unit that `parse_size` reads back: `8G`, `512M`, `0`.
pub fn format_size(bytes: u64) -> String {
    for (suffix, shift) in [("T", 40), ("G", 30), ("M", 20), ("K", 10)] {
        if bytes >= 1 << shift && bytes.is_multiple_of(1 << shift) {
            return format!("{}{suffix}", bytes >> shift);
        }
    }
    bytes.to_string()
}

/// A flag's help text followed by its default, as clap shows defaults: `TEXT [default: X]`.
pub fn with_default(text: &str, default: impl std::fmt::Display) -> String {
    format!("{text} [default: {default}]")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn units_parse() {
        assert_eq!(parse_duration("10m"), Ok(600.0));
        assert_eq!(parse_duration("90"), Ok(90.0));
        assert_eq!(parse_duration("1.5h"), Ok(5400.0));
        assert!(parse_duration("ten").is_err());
        assert_eq!(parse_size("8G"), Ok(8 << 30));
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size("0"), Ok(0));
        assert!(parse_size("lots").is_err());
        assert_eq!(format_seconds(3725.0), "1h02m");
        assert_eq!(format_size(8 << 30), "8G");
        assert_eq!(format_size(1536 << 20), "1536M");
        assert_eq!(format_size(0), "0");
        assert_eq!(parse_size(&format_size(1536 << 20)), Ok(1536 << 20));
    }
}
