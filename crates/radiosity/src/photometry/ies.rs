//! IES LM-63 reader (ANSI/IES LM-63-1986, -1991, -1995, -2002, -2019).
//!
//! Layout, as the standard's revisions agree on it:
//!
//! ```text
//! IESNA:LM-63-2002                  version line (absent in 1986; IESNA91, IESNA:LM-63-1995,
//!                                   IES:LM-63-2019 for the others)
//! [TEST] …  [MANUFAC] …  [MORE] …   label lines up to the TILT line (1986: free text)
//! TILT=NONE                         (INCLUDE and <file> are refused: no tilt tables here)
//! #lamps lumens/lamp multiplier #vertical #horizontal type units width length height
//! ballast-factor <ballast-lamp factor | future use | file generation type> input-watts
//! vertical angles (γ)               #vertical values
//! horizontal angles (C)             #horizontal values
//! candela                           #horizontal rows of #vertical values, C-major
//! ```
//!
//! After the TILT line everything is a stream of numbers separated by whitespace or commas,
//! free to span lines (LM-63 breaks long records onto as many lines as needed), so the
//! reader counts values, not lines: exactly 13 + V + H + V·H of them, where too few is an
//! error naming what is missing and any extra one is an error at its line.
//!
//! Checks: counts whole numbers (LM-63-1986 allows "3.0"), V in 2…[`MAX_ANGLES`], H in
//! 1…[`MAX_ANGLES`], V·H ≤ [`MAX_VALUES`]; photometric type 1 (C; types 2, B, and 3, A,
//! are refused); units 1 (feet) or 2 (metres); multiplier and ballast factor finite and > 0;
//! lumens per lamp > 0 or exactly −1 (absolute photometry); vertical angles in [0°, 180°],
//! non-decreasing, first < last; horizontal angles in [0°, 360°], strictly increasing, and
//! one of the type C forms of LM-63-2002 §"horizontal angles" — a single 0° (rotational
//! symmetry), 0…90° (quadrant), 0…180° (bilateral), 0…(180°, 360°] (none) — or LM-63-1995's
//! 90…270° (bilateral about the C90–C270 plane); candela finite and ≥ 0.
//!
//! Scaling: candela × multiplier × ballast factor, × ballast-lamp photometric factor for
//! 1986 and 1991 only (the field is "future use" in 1995 and 2002 and the file generation
//! type in 2019; Radiance's ies2rad makes the same distinction). Dimensions in feet are
//! converted at 0.3048 m/ft.
//!
//! Deliberately lenient, for real files: the label section is kept as text and not checked
//! against each revision's keyword list (LM-63-2019's required `[TEST]`, `[TESTLAB]`,
//! `[ISSUEDATE]`, `[MANUFAC]` are not enforced); lines may end in CR LF, LF or CR; the
//! 80/132/256-character line limits of the revisions are not enforced; a DOS end-of-file
//! character (Ctrl-Z) counts as white space.

use super::{
    check_text, split_lines, IesVersion, LuminousOpening, Metadata, Photometry, PhotometryError,
    SourceFormat, StoredTable, Symmetry, Tokens, MAX_ANGLES, MAX_VALUES,
};

/// Metres per foot (LM-63 units type 1).
const METRES_PER_FOOT: f64 = 0.3048;

/// Reads LM-63 text; see the module documentation.
pub(super) fn parse(text: &str, file: &str) -> Result<Photometry, PhotometryError> {
    let text = check_text(text, file)?;
    let lines = split_lines(text);
    let syntax = |line: usize, message: String| PhotometryError::Syntax {
        file: file.to_string(),
        line,
        message,
    };
    let unsupported = |line: usize, message: String| PhotometryError::Unsupported {
        file: file.to_string(),
        line,
        message,
    };

    // Version line (index 0 is line 1).
    let (version, label_start) = match version_of(lines[0].trim()) {
        Version::Known(v) => (v, 1),
        Version::None => (IesVersion::Lm63_1986, 0),
        Version::Unknown => {
            return Err(unsupported(
                1,
                format!(
                    "unknown LM-63 version line '{}' (expected IESNA91, IESNA:LM-63-1995, \
                     IESNA:LM-63-2002 or IES:LM-63-2019, or none for LM-63-1986)",
                    lines[0].trim()
                ),
            ))
        }
    };

    // Label lines up to TILT=.
    let mut keywords: Vec<(String, String)> = Vec::new();
    let mut tilt = None;
    for (k, line) in lines.iter().enumerate().skip(label_start) {
        if let Some(value) = tilt_value(line) {
            tilt = Some((k, value));
            break;
        }
        read_label(line, version, &mut keywords);
    }
    let Some((tilt_index, tilt)) = tilt else {
        return Err(syntax(
            lines.len().max(1),
            "no 'TILT=' line: the label section never ends (is this an IES LM-63 file?)"
                .to_string(),
        ));
    };
    let tilt_line = tilt_index + 1;
    if !tilt.eq_ignore_ascii_case("NONE") {
        return Err(if tilt.eq_ignore_ascii_case("INCLUDE") {
            unsupported(
                tilt_line,
                "TILT=INCLUDE (lamp-tilt multiplier table) is not supported; only TILT=NONE is"
                    .to_string(),
            )
        } else if tilt.is_empty() {
            syntax(
                tilt_line,
                "'TILT=' has no value (expected NONE)".to_string(),
            )
        } else {
            unsupported(
                tilt_line,
                format!(
                    "TILT={tilt} (lamp-tilt data in a separate file) is not supported; only \
                     TILT=NONE is"
                ),
            )
        });
    }

    // The numeric records.
    let mut tokens = Tokens::new(&lines[tilt_index + 1..], tilt_line + 1, &[','], file);
    let lamps = tokens.integer("number of lamps", 1, 1_000_000)?;
    let (lumens_token, lumens_per_lamp) = tokens.number("lumens per lamp")?;
    let absolute = lumens_per_lamp == -1.0;
    if !absolute && lumens_per_lamp <= 0.0 {
        return Err(syntax(
            lumens_token.line,
            format!(
                "lumens per lamp is {}: must be positive, or -1 for absolute photometry",
                lumens_token.text
            ),
        ));
    }
    let (multiplier_token, multiplier) = tokens.number("candela multiplier")?;
    if multiplier <= 0.0 {
        return Err(syntax(
            multiplier_token.line,
            format!(
                "candela multiplier is {}: must be positive",
                multiplier_token.text
            ),
        ));
    }
    let n_vertical = tokens.integer("number of vertical angles", 2, MAX_ANGLES as i64)? as usize;
    let horizontal_token_line = tokens.next_line();
    let n_horizontal =
        tokens.integer("number of horizontal angles", 1, MAX_ANGLES as i64)? as usize;
    if n_vertical * n_horizontal > MAX_VALUES {
        return Err(syntax(
            horizontal_token_line,
            format!(
                "{n_vertical} vertical × {n_horizontal} horizontal angles is {} candela values, \
                 over the limit of {MAX_VALUES}",
                n_vertical * n_horizontal
            ),
        ));
    }
    let type_line = tokens.next_line();
    match tokens.integer("photometric type", i64::MIN, i64::MAX)? {
        1 => {}
        2 => {
            return Err(unsupported(
                type_line,
                "photometric type 2 (type B) is not supported; only type C (1) is".to_string(),
            ))
        }
        3 => {
            return Err(unsupported(
                type_line,
                "photometric type 3 (type A) is not supported; only type C (1) is".to_string(),
            ))
        }
        other => {
            return Err(syntax(
                type_line,
                format!("photometric type is {other}: must be 1 (C), 2 (B) or 3 (A)"),
            ))
        }
    }
    let units_line = tokens.next_line();
    let metres_per_unit = match tokens.integer("units type", i64::MIN, i64::MAX)? {
        1 => METRES_PER_FOOT,
        2 => 1.0,
        other => {
            return Err(syntax(
                units_line,
                format!("units type is {other}: must be 1 (feet) or 2 (metres)"),
            ))
        }
    };
    let (_, width) = tokens.number("luminous opening width")?;
    let (_, length) = tokens.number("luminous opening length")?;
    let (_, height) = tokens.number("luminous opening height")?;
    let (ballast_token, ballast_factor) = tokens.number("ballast factor")?;
    if ballast_factor <= 0.0 {
        return Err(syntax(
            ballast_token.line,
            format!("ballast factor is {}: must be positive", ballast_token.text),
        ));
    }
    let second_field = match version {
        IesVersion::Lm63_1986 | IesVersion::Lm63_1991 => "ballast-lamp photometric factor",
        IesVersion::Lm63_1995 | IesVersion::Lm63_2002 => "future-use field",
        IesVersion::Lm63_2019 => "file generation type",
    };
    let (second_token, second) = tokens.number(second_field)?;
    let lamp_factor = if version <= IesVersion::Lm63_1991 {
        if second <= 0.0 {
            return Err(syntax(
                second_token.line,
                format!(
                    "ballast-lamp photometric factor is {}: must be positive",
                    second_token.text
                ),
            ));
        }
        second
    } else {
        1.0
    };
    let (_, input_watts) = tokens.number("input watts")?;

    let (gamma, _) = tokens.angles(n_vertical, "vertical angles", (0.0, 180.0), false)?;
    if gamma[n_vertical - 1] <= gamma[0] {
        return Err(syntax(
            tokens.previous_line(),
            format!(
                "vertical angles span nothing: all are {}°; the first must be below the last",
                gamma[0]
            ),
        ));
    }
    let (c_deg, c_lines) = tokens.angles(n_horizontal, "horizontal angles", (0.0, 360.0), true)?;
    let symmetry =
        horizontal_symmetry(&c_deg).map_err(|(index, message)| syntax(c_lines[index], message))?;
    let scale = multiplier * ballast_factor * lamp_factor;
    let candela = tokens.intensities(n_vertical * n_horizontal, "candela values", scale)?;
    tokens.finish("the candela table")?;

    let find = |key: &str| {
        keywords
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(key))
            .map(|(_, v)| v.clone())
    };
    let metadata = Metadata {
        format: SourceFormat::Ies(version),
        manufacturer: find("MANUFAC"),
        catalogue: find("LUMCAT"),
        luminaire: find("LUMINAIRE"),
        lamp: find("LAMP"),
        input_watts: Some(input_watts),
        light_output_ratio: None,
        file_generation_type: (version == IesVersion::Lm63_2019)
            .then(|| second_token.text.to_string()),
        keywords,
    };
    let opening = LuminousOpening {
        width_m: width * metres_per_unit,
        length_m: length * metres_per_unit,
        height_m: height * metres_per_unit,
    };
    let lamp_lumens = (!absolute).then_some(lumens_per_lamp * lamps as f64);
    let table = StoredTable {
        symmetry,
        c_deg,
        gamma_deg: gamma,
        candela,
    };
    Ok(Photometry::from_stored(
        file,
        table,
        lamp_lumens,
        opening,
        metadata,
    ))
}

/// What the first line says about the version.
enum Version {
    Known(IesVersion),
    /// Not a version line: LM-63-1986, whose first line is already a label.
    None,
    /// Looks like a version line but names no revision we know.
    Unknown,
}

fn version_of(first: &str) -> Version {
    let upper = first.to_ascii_uppercase();
    match upper.as_str() {
        "IESNA91" | "IESNA:LM-63-1991" => Version::Known(IesVersion::Lm63_1991),
        "IESNA:LM-63-1995" => Version::Known(IesVersion::Lm63_1995),
        "IESNA:LM-63-2002" => Version::Known(IesVersion::Lm63_2002),
        "IES:LM-63-2019" | "IESNA:LM-63-2019" => Version::Known(IesVersion::Lm63_2019),
        _ if upper.starts_with("IESNA") || upper.starts_with("IES:LM-63") => Version::Unknown,
        _ => Version::None,
    }
}

/// The value after `TILT=` if `line` is the TILT line (leading blanks and blanks around `=`
/// allowed, `TILT` in any case).
fn tilt_value(line: &str) -> Option<&str> {
    let line = line.trim();
    let head = line.get(..4)?;
    if !head.eq_ignore_ascii_case("TILT") {
        return None;
    }
    let rest = line[4..].trim_start().strip_prefix('=')?;
    Some(rest.trim())
}

/// Adds one label line to `keywords`: `[KEY] value` (1991 on), `[MORE] text` continuing the
/// previous keyword, anything else (and every 1986 line) as free text under the key "".
fn read_label(line: &str, version: IesVersion, keywords: &mut Vec<(String, String)>) {
    let trimmed = line.trim();
    if trimmed.is_empty() {
        return;
    }
    if version > IesVersion::Lm63_1986 {
        if let Some(rest) = trimmed.strip_prefix('[') {
            if let Some((key, value)) = rest.split_once(']') {
                let key = key.trim();
                let value = value.trim();
                if key.eq_ignore_ascii_case("MORE") {
                    if let Some((_, previous)) = keywords.last_mut() {
                        previous.push('\n');
                        previous.push_str(value);
                        return;
                    }
                }
                keywords.push((key.to_string(), value.to_string()));
                return;
            }
        }
    }
    keywords.push((String::new(), trimmed.to_string()));
}

/// The symmetry a type C horizontal-angle list declares (LM-63-2002, "horizontal angles";
/// LM-63-1995 for 90…270), or the index of the offending angle and what is wrong with it.
/// Angles are strictly increasing within [0°, 360°] already.
fn horizontal_symmetry(c: &[f64]) -> Result<Symmetry, (usize, String)> {
    let last_index = c.len() - 1;
    let first = c[0];
    let last = c[c.len() - 1];
    if c.len() == 1 {
        return if first == 0.0 {
            Ok(Symmetry::Rotational)
        } else {
            Err((
                0,
                format!(
                    "first horizontal angle is {first}°: a single horizontal angle must be 0° \
                     (rotational symmetry)"
                ),
            ))
        };
    }
    if first == 90.0 {
        return if last == 270.0 {
            Ok(Symmetry::BilateralC90C270)
        } else {
            Err((
                last_index,
                format!(
                    "last horizontal angle is {last}°: horizontal angles starting at 90° must \
                     end at 270° (symmetry about the C90–C270 plane)"
                ),
            ))
        };
    }
    if first != 0.0 {
        return Err((
            0,
            format!(
                "first horizontal angle is {first}°: must be 0° (or 90° for a 90°–270° \
                 distribution)"
            ),
        ));
    }
    if last == 90.0 {
        Ok(Symmetry::Quadrant)
    } else if last == 180.0 {
        Ok(Symmetry::BilateralC0C180)
    } else if last > 180.0 {
        Ok(Symmetry::None)
    } else {
        Err((
            last_index,
            format!(
                "last horizontal angle is {last}°: must be 0°, 90°, 180° or in (180°, 360°] \
                 (type C symmetry)"
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::ies_file;
    use super::super::*;
    use std::f64::consts::PI;

    const BODY: &str = "TILT=NONE\n1 1000 1 3 1 1 2 0.6 0.6 0.1\n1 1 30\n0 45 90\n0\n100 80 0\n";

    #[test]
    fn reads_every_version_and_its_keywords() {
        let cases = [
            ("", IesVersion::Lm63_1986),
            ("IESNA91\n", IesVersion::Lm63_1991),
            ("IESNA:LM-63-1995\n", IesVersion::Lm63_1995),
            ("IESNA:LM-63-2002\n", IesVersion::Lm63_2002),
            ("IES:LM-63-2019\n", IesVersion::Lm63_2019),
        ];
        for (head, version) in cases {
            let labels = if version == IesVersion::Lm63_1986 {
                "ACME LIGHTING TEST 123\nA FREE-FORM LABEL\n"
            } else {
                "[TEST] 123\n[MANUFAC] ACME\n[LUMINAIRE] Downlight\n[MORE] with louvre\n"
            };
            let text = format!("{head}{labels}{BODY}");
            let p = from_ies(&text, "v.ies").unwrap_or_else(|e| panic!("{version:?}: {e}"));
            assert_eq!(p.metadata.format, SourceFormat::Ies(version));
            assert_eq!(p.lamp_lumens, Some(1000.0));
            assert_eq!(p.intensity(0.0, 0.0), 100.0);
            assert_eq!(p.intensity(123.0, 45.0), 80.0);
            if version == IesVersion::Lm63_1986 {
                assert_eq!(p.metadata.keywords.len(), 2);
                assert_eq!(p.metadata.keywords[0].0, "");
                assert_eq!(p.metadata.manufacturer, None);
            } else {
                assert_eq!(p.metadata.manufacturer.as_deref(), Some("ACME"));
                assert_eq!(
                    p.metadata.luminaire.as_deref(),
                    Some("Downlight\nwith louvre")
                );
            }
            assert_eq!(
                p.metadata.file_generation_type.is_some(),
                version == IesVersion::Lm63_2019
            );
        }
    }

    #[test]
    fn lm63_2019_file_generation_info_is_metadata_not_a_multiplier() {
        let text = "IES:LM-63-2019\n[TEST] 1\n[TESTLAB] lab\n[ISSUEDATE] 2024-01-01\n\
                    [MANUFAC] m\n[FILEGENINFO] simulated, written for a unit test\n\
                    TILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n1 1.10100 30\n0 45 90\n0\n100 80 0\n";
        let p = from_ies(text, "2019.ies").unwrap();
        assert_eq!(p.metadata.file_generation_type.as_deref(), Some("1.10100"));
        assert_eq!(p.intensity(0.0, 0.0), 100.0);
        assert_eq!(p.lamp_lumens, None);
        assert!(p
            .metadata
            .keywords
            .iter()
            .any(|(k, v)| k == "FILEGENINFO" && v.starts_with("simulated")));
    }

    #[test]
    fn multipliers_apply_as_each_version_defines_them() {
        // multiplier 2, ballast factor 0.9, second field 0.5.
        let body = "TILT=NONE\n2 500 2 2 1 1 1 1 2 0.5\n0.9 0.5 30\n0 90\n0\n100 10\n";
        let scaled = |head: &str| from_ies(&format!("{head}{body}"), "m.ies").unwrap();
        // 1986/1991: × 2 × 0.9 × 0.5 (ballast-lamp photometric factor).
        assert!((scaled("IESNA91\n").intensity(0.0, 0.0) - 90.0).abs() < 1e-12);
        assert!((scaled("LABEL\n").intensity(0.0, 0.0) - 90.0).abs() < 1e-12);
        // 1995/2002/2019: the second field is not a factor: × 2 × 0.9.
        for head in [
            "IESNA:LM-63-1995\n",
            "IESNA:LM-63-2002\n",
            "IES:LM-63-2019\n",
        ] {
            assert!(
                (scaled(head).intensity(0.0, 0.0) - 180.0).abs() < 1e-12,
                "{head}"
            );
        }
        let p = scaled("IESNA:LM-63-2002\n");
        assert_eq!(p.lamp_lumens, Some(1000.0));
        // Units type 1: feet.
        assert!((p.opening.width_m - 0.3048).abs() < 1e-15);
        assert!((p.opening.length_m - 0.6096).abs() < 1e-15);
        assert!((p.opening.height_m - 0.1524).abs() < 1e-15);
        assert_eq!(p.metadata.input_watts, Some(30.0));
    }

    #[test]
    fn numbers_may_span_lines_and_use_commas() {
        let text = "IESNA:LM-63-2002\nTILT=NONE\n1,1000,1,\n3 2 1\n2 0.6,0.6 0 1\n1\n30 0 45\n\
                    90\n0, 180\n100\n80 0 100 80\n0\n";
        let p = from_ies(text, "wrapped.ies").unwrap();
        assert_eq!(p.symmetry, Symmetry::BilateralC0C180);
        assert_eq!(p.intensity(90.0, 45.0), 80.0);
        // CR-only and CR LF line ends.
        let cr = text.replace('\n', "\r");
        assert!(from_ies(&cr, "cr.ies").is_ok());
        let crlf = text.replace('\n', "\r\n");
        assert!(from_ies(&crlf, "crlf.ies").is_ok());
    }

    #[test]
    fn absolute_photometry_has_no_lamp_lumens() {
        let vertical = [0.0, 90.0];
        let p = from_ies(&ies_file(&vertical, &[0.0], &[vec![10.0, 0.0]]), "abs.ies").unwrap();
        assert_eq!(p.lamp_lumens, None);
        assert_eq!(p.light_output_ratio(), None);
        // Φ of 10 cd falling linearly to 0 over 90°: 2π·10·w₀ with w₀ = 1 − 2/π.
        assert!((p.flux() - 2.0 * PI * 10.0 * (1.0 - 2.0 / PI)).abs() < 1e-12);
    }

    /// (what the case is, file text, the line the error must name, a word in the message)
    fn malformed_cases() -> Vec<(&'static str, String, usize, &'static str)> {
        let v = "IESNA:LM-63-2002\n[TEST] x\nTILT=NONE\n";
        let good_rest = "1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n";
        let with = |rest: &str| format!("{v}{rest}");
        vec![
            ("empty file", String::new(), 1, "empty"),
            ("blank file", "\n  \n\t\n".to_string(), 1, "empty"),
            (
                "no TILT line",
                "IESNA:LM-63-2002\n[TEST] x\n[MANUFAC] y\n".to_string(),
                3,
                "TILT",
            ),
            (
                "unknown version",
                format!("IESNA:LM-63-2099\nTILT=NONE\n{good_rest}"),
                1,
                "version",
            ),
            (
                "TILT=INCLUDE",
                format!("IESNA:LM-63-2002\n[TEST] x\nTILT=INCLUDE\n1\n2\n0 90\n1 1\n{good_rest}"),
                3,
                "INCLUDE",
            ),
            (
                "TILT=<file>",
                format!("IESNA:LM-63-2002\nTILT=lamp.tlt\n{good_rest}"),
                2,
                "lamp.tlt",
            ),
            (
                "TILT= empty",
                format!("IESNA:LM-63-2002\nTILT=\n{good_rest}"),
                2,
                "no value",
            ),
            (
                "type B",
                with("1 1000 1 3 1 2 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "type B",
            ),
            (
                "type A",
                with("1 1000 1 3 1 3 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "type A",
            ),
            (
                "type 7",
                with("1 1000 1 3 1 7 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "photometric type",
            ),
            (
                "units 3",
                with("1 1000 1 3 1 1 3 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "units",
            ),
            (
                "negative vertical count",
                with("1 1000 1 -3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "vertical",
            ),
            (
                "zero horizontal count",
                with("1 1000 1 3 0 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "horizontal",
            ),
            (
                "fractional count",
                with("1 1000 1 3.5 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "whole",
            ),
            (
                "huge vertical count",
                with("1 1000 1 99999999 1 1 2 0 0 0\n1 1 30\n"),
                4,
                "between",
            ),
            (
                "huge product",
                with("1 1000 1 10000\n10000 1 2 0 0 0\n1 1 30\n"),
                5,
                "over the limit",
            ),
            (
                "zero lamps",
                with("0 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "lamps",
            ),
            (
                "negative lumens",
                with("1 -5 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "-1",
            ),
            (
                "zero multiplier",
                with("1 1000 0 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0\n"),
                4,
                "multiplier",
            ),
            (
                "zero ballast factor",
                with("1 1000 1 3 1 1 2 0 0 0\n0 1 30\n0 45 90\n0\n100 80 0\n"),
                5,
                "ballast",
            ),
            (
                "NaN candela",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 NaN 0\n"),
                8,
                "finite",
            ),
            (
                "infinite candela",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 inf 0\n"),
                8,
                "finite",
            ),
            (
                "negative candela",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 -80 0\n"),
                8,
                "negative",
            ),
            (
                "word for a number",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 ninety\n0\n100 80 0\n"),
                6,
                "not a number",
            ),
            (
                "NaN angle",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 NaN 90\n0\n100 80 0\n"),
                6,
                "finite",
            ),
            (
                "decreasing vertical",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 90 45\n0\n100 80 0\n"),
                6,
                "non-decreasing",
            ),
            (
                "vertical beyond 180",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 90 190\n0\n100 80 0\n"),
                6,
                "outside",
            ),
            (
                "vertical span zero",
                with("1 1000 1 2 1 1 2 0 0 0\n1 1 30\n45 45\n0\n100 80\n"),
                6,
                "span nothing",
            ),
            (
                "repeated horizontal",
                with("1 1000 1 2 3 1 2 0 0 0\n1 1 30\n0 90\n0 45 45\n1 1\n1 1\n1 1\n"),
                7,
                "increasing",
            ),
            (
                "decreasing horizontal",
                with("1 1000 1 2 3 1 2 0 0 0\n1 1 30\n0 90\n0 90 45\n1 1\n1 1\n1 1\n"),
                7,
                "increasing",
            ),
            (
                "horizontal not from 0",
                with("1 1000 1 2 2 1 2 0 0 0\n1 1 30\n0 90\n10 90\n1 1\n1 1\n"),
                7,
                "first horizontal",
            ),
            (
                "horizontal ends at 120",
                with("1 1000 1 2 2 1 2 0 0 0\n1 1 30\n0 90\n0 120\n1 1\n1 1\n"),
                7,
                "last horizontal",
            ),
            (
                "single horizontal not 0",
                with("1 1000 1 2 1 1 2 0 0 0\n1 1 30\n0 90\n45\n1 1\n"),
                7,
                "single",
            ),
            (
                "90 to 200",
                with("1 1000 1 2 2 1 2 0 0 0\n1 1 30\n0 90\n90 200\n1 1\n1 1\n"),
                7,
                "270",
            ),
            (
                "truncated header",
                with("1 1000 1 3 1 1 2 0 0\n"),
                4,
                "height",
            ),
            (
                "truncated candela",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80\n"),
                8,
                "candela",
            ),
            (
                "extra candela",
                with("1 1000 1 3 1 1 2 0 0 0\n1 1 30\n0 45 90\n0\n100 80 0 5\n"),
                8,
                "extra",
            ),
            (
                "trailing text",
                format!("{}{}x\n", v, good_rest),
                9,
                "extra",
            ),
            (
                "binary garbage",
                "IESNA:LM-63-2002\n\u{1}\u{2}\u{fffd}\0\u{7f}".to_string(),
                2,
                "NUL",
            ),
            (
                "garbage without NUL",
                "\u{1}\u{2}\u{3}ÿþ\n\u{5}\u{6}".to_string(),
                2,
                "TILT",
            ),
        ]
    }

    #[test]
    fn malformed_files_fail_with_file_line_and_reason() {
        let cases = malformed_cases();
        assert!(cases.len() >= 20);
        for (what, text, line, word) in cases {
            let e = match from_ies(&text, "bad.ies") {
                Ok(_) => panic!("{what}: accepted"),
                Err(e) => e,
            };
            let message = e.to_string();
            assert_eq!(e.line(), Some(line), "{what}: {message}");
            assert!(
                message.starts_with(&format!("bad.ies: line {line}: ")),
                "{what}: {message}"
            );
            assert!(message.contains(word), "{what}: '{word}' not in: {message}");
        }
    }

    #[test]
    fn tilt_line_variants() {
        assert_eq!(super::tilt_value("TILT=NONE"), Some("NONE"));
        assert_eq!(super::tilt_value("  tilt = none  "), Some("none"));
        assert_eq!(super::tilt_value("TILTED"), None);
        assert_eq!(super::tilt_value("[TILT] x"), None);
        assert_eq!(super::tilt_value("TIL"), None);
        // A multibyte character where the keyword would be must not panic.
        assert_eq!(super::tilt_value("TIé=NONE"), None);
    }
}
