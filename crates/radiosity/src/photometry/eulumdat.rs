//! EULUMDAT reader (`.ldt`; Stockmar 1990, "EULUMDAT – ein Leuchtendatenformat für den
//! europäischen Beleuchtungsplaner", and the EULUMDAT/2 line table, Stockmar 1998).
//!
//! Layout, one field per line:
//!
//! ```text
//!  1  company identification / data bank / version      (text)
//!  2  Ityp, type indicator 0…3                           (kept as metadata only)
//!  3  Isym, symmetry indicator 0…4
//!  4  Mc, number of C planes in 0…360°      5  Dc, C-plane spacing (0: not equidistant)
//!  6  Ng, number of γ angles per plane      7  Dg, γ spacing (0: not equidistant)
//!  8  measurement report  9  luminaire name  10  luminaire number  11  file name  12  date/user
//! 13–15  luminaire length/diameter, width (0: circular), height, mm
//! 16–17  luminous area length/diameter, width (0: circular), mm
//! 18–21  luminous area height in the C0, C90, C180, C270 planes, mm
//! 22  downward flux fraction DFF, %        23  light output ratio LORL, %
//! 24  conversion factor for luminous intensities
//! 25  tilt of the luminaire during measurement, degrees
//! 26  n, number of lamp sets; then per set, six lines: number of lamps, type of lamps,
//!     total luminous flux of the lamps (lm), colour temperature, colour rendering
//!     group/index, wattage including ballast (W)
//! 27  ten direct ratios (room indices k = 0.6 … 5)
//! 28  Mc C angles                            29  Ng γ angles
//! 30  intensities, cd/klm, Ng per stored C plane, planes in the order of the C-angle list
//! ```
//!
//! Stored C planes by Isym (indices into the C-angle list of line 28, 0-based):
//! 0, no symmetry: all Mc; 1, rotational: the first (C0); 2, symmetric about C0–C180:
//! 0…Mc/2 (C0…C180); 3, symmetric about C90–C270: Mc/4…3Mc/4 (C90…C270); 4, both planes:
//! 0…Mc/4 (C0…C90). For Isym 3 the published line table gives the first stored plane as
//! "Mc1 = 3·Mc/4 + 1", which with "Mc2 = Mc1 + Mc/2" runs past the Mc planes of the list; we
//! read C90…C270, the half-plane range that symmetry about the C90–C270 plane needs and that
//! parsers in use read. Isym 2 needs Mc even, Isym 3 and 4 need Mc divisible by 4, and the
//! listed angles at the boundaries must be exactly 90°, 180°, 270° as the symmetry requires.
//!
//! Conversion to candela: I = value × conversion factor (line 24) × Φ₁ / 1000, with Φ₁ the
//! total luminous flux of the **first** lamp set (line 26c); further lamp sets (alternative
//! equipment) are kept as metadata but do not scale the table. A **negative number of
//! lamps** in the first set marks absolute photometry (a convention of LED data): Φ₁ is then
//! the luminaire's own flux, the conversion is the same, and
//! [`super::Photometry::lamp_lumens`] is `None`. With a positive count it is `Some(Φ₁)`;
//! Φ₁ is already the total for the set, not per lamp. A count of 0 is an error.
//!
//! Leniency for real files: the arrays of lines 27–30 are read as whitespace-separated
//! values, so a writer that puts several on one line is accepted; a decimal comma ("0,85")
//! is accepted in any number; Dc and Dg are not checked against the listed angles (the lists
//! are what the table uses); DFF, LORL and the direct ratios are not checked against the
//! table (LORL is kept as metadata). Lines may end in CR LF, LF or CR.

use super::{
    check_text, split_lines, LuminousOpening, Metadata, Photometry, PhotometryError, SourceFormat,
    StoredTable, Symmetry, Tokens, MAX_ANGLES, MAX_VALUES,
};

/// Most lamp sets accepted (the format's line table allows 20; some writers exceed it).
const MAX_LAMP_SETS: i64 = 1000;

/// Reads EULUMDAT text; see the module documentation.
pub(super) fn parse(text: &str, file: &str) -> Result<Photometry, PhotometryError> {
    let text = check_text(text, file)?;
    let lines = split_lines(text);
    let mut fields = Fields {
        lines: &lines,
        next: 0,
        file,
    };
    let syntax = |line: usize, message: String| PhotometryError::Syntax {
        file: file.to_string(),
        line,
        message,
    };

    let company = fields.text("company identification (line 1)")?;
    let _ityp = fields.integer("type indicator Ityp", 0, 3)?;
    let (isym_line, isym) = fields.integer_at("symmetry indicator Isym", 0, 4)?;
    let (mc_line, mc) = fields.integer_at("number of C planes Mc", 1, MAX_ANGLES as i64)?;
    let mc = mc as usize;
    let _dc = fields.non_negative("C-plane spacing Dc")?;
    let (ng_line, ng) = fields.integer_at("number of γ angles Ng", 2, MAX_ANGLES as i64)?;
    let ng = ng as usize;
    let _dg = fields.non_negative("γ spacing Dg")?;
    let report = fields.text("measurement report number")?;
    let name = fields.text("luminaire name")?;
    let number = fields.text("luminaire number")?;
    let file_name = fields.text("file name")?;
    let date = fields.text("date/user")?;
    for what in [
        "luminaire length/diameter",
        "luminaire width",
        "luminaire height",
    ] {
        fields.number(what)?;
    }
    let area_length = fields.number("luminous area length/diameter")?;
    let area_width = fields.number("luminous area width")?;
    let mut area_height = 0.0_f64;
    for plane in ["C0", "C90", "C180", "C270"] {
        area_height = area_height.max(fields.number(&format!("luminous area height {plane}"))?);
    }
    let _dff = fields.number("downward flux fraction DFF")?;
    let lorl = fields.number("light output ratio LORL")?;
    let (cf_line, conversion) = fields.number_at("conversion factor for luminous intensities")?;
    if conversion <= 0.0 {
        return Err(syntax(
            cf_line,
            format!("conversion factor for luminous intensities is {conversion}: must be positive"),
        ));
    }
    let _tilt = fields.number("tilt during measurement")?;
    let sets = fields.integer("number of lamp sets n", 1, MAX_LAMP_SETS)?;
    let mut lamp_sets = Vec::new();
    for set in 1..=sets {
        let (count_line, count) = fields.integer_at(
            &format!("number of lamps (set {set})"),
            -1_000_000,
            1_000_000,
        )?;
        if count == 0 {
            return Err(syntax(
                count_line,
                format!(
                    "number of lamps (set {set}) is 0: must be positive, or negative for \
                     absolute photometry"
                ),
            ));
        }
        let kind = fields.text(&format!("type of lamps (set {set})"))?;
        let (flux_line, flux) = fields.number_at(&format!("total luminous flux (set {set})"))?;
        if flux <= 0.0 {
            return Err(syntax(
                flux_line,
                format!("total luminous flux (set {set}) is {flux} lm: must be positive"),
            ));
        }
        let cct = fields.text(&format!("colour temperature (set {set})"))?;
        let cri = fields.text(&format!("colour rendering index (set {set})"))?;
        let watts = fields.number(&format!("wattage (set {set})"))?;
        lamp_sets.push(LampSet {
            count,
            kind,
            flux,
            cct,
            cri,
            watts,
        });
    }

    // Lines 27–30 as a stream of values.
    let start = fields.next;
    let mut tokens = Tokens::new(&lines[start..], start + 1, &[], file).with_decimal_comma();
    tokens.ensure(10, "direct ratios")?;
    for _ in 0..10 {
        tokens.number("direct ratio")?;
    }
    let (c_list, c_lines) = tokens.angles(mc, "C angles", (0.0, 360.0), true)?;
    if c_list[0] != 0.0 {
        return Err(syntax(
            c_lines[0],
            format!("first C angle is {}°: must be 0°", c_list[0]),
        ));
    }
    let (gamma, _) = tokens.angles(ng, "γ angles", (0.0, 180.0), false)?;
    if gamma[ng - 1] <= gamma[0] {
        return Err(syntax(
            tokens.previous_line(),
            format!(
                "γ angles span nothing: all are {}°; the first must be below the last",
                gamma[0]
            ),
        ));
    }
    let (symmetry, stored) = stored_planes(isym, mc, &c_list).map_err(|problem| match problem {
        PlaneProblem::Count(message) => syntax(mc_line, message),
        PlaneProblem::Angle(index, message) => syntax(c_lines[index], message),
    })?;
    let c_deg = c_list[stored.clone()].to_vec();
    let n_values = c_deg.len() * ng;
    if n_values > MAX_VALUES {
        return Err(syntax(
            ng_line,
            format!(
                "{} stored C planes × {ng} γ angles is {n_values} values, over the limit of \
                 {MAX_VALUES}",
                c_deg.len()
            ),
        ));
    }
    let first = &lamp_sets[0];
    let scale = conversion * first.flux / 1000.0;
    let what = format!(
        "luminous intensities (cd/klm; {} C plane(s) × {ng} for Isym {isym} from line {isym_line})",
        c_deg.len()
    );
    let candela = tokens.intensities(n_values, &what, scale)?;
    tokens.finish("the intensity table")?;

    let mut keywords = vec![
        ("COMPANY".to_string(), company.clone()),
        ("REPORT".to_string(), report),
        ("LUMINAIRE".to_string(), name.clone()),
        ("LUMCAT".to_string(), number.clone()),
        ("FILENAME".to_string(), file_name),
        ("DATE".to_string(), date),
    ];
    for (k, set) in lamp_sets.iter().enumerate() {
        keywords.push((
            format!("LAMPSET{}", k + 1),
            format!(
                "{} × {}, {} lm, {}, CRI {}, {} W",
                set.count, set.kind, set.flux, set.cct, set.cri, set.watts
            ),
        ));
    }
    let non_empty = |s: String| (!s.is_empty()).then_some(s);
    let metadata = Metadata {
        format: SourceFormat::Eulumdat,
        keywords,
        manufacturer: non_empty(company),
        catalogue: non_empty(number),
        luminaire: non_empty(name),
        lamp: non_empty(first.kind.clone()),
        input_watts: Some(first.watts),
        light_output_ratio: Some(lorl / 100.0),
        file_generation_type: None,
    };
    let opening = LuminousOpening {
        width_m: area_width / 1000.0,
        length_m: area_length / 1000.0,
        height_m: area_height / 1000.0,
    };
    let lamp_lumens = (first.count > 0).then_some(first.flux);
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

/// One lamp set (lines 26a–f).
struct LampSet {
    count: i64,
    kind: String,
    flux: f64,
    cct: String,
    cri: String,
    watts: f64,
}

/// Why the C-angle list does not fit the declared symmetry.
enum PlaneProblem {
    /// Mc does not divide as the symmetry needs (reported at the Mc line).
    Count(String),
    /// The listed angle at this index is not the boundary the symmetry needs.
    Angle(usize, String),
}

/// The symmetry Isym declares and the range of C-list indices whose planes are stored.
fn stored_planes(
    isym: i64,
    mc: usize,
    c: &[f64],
) -> Result<(Symmetry, std::ops::RangeInclusive<usize>), PlaneProblem> {
    let divisible = |k: usize| {
        if mc % k == 0 {
            Ok(())
        } else {
            Err(PlaneProblem::Count(format!(
                "Mc = {mc} C planes cannot be split as Isym {isym} needs (a multiple of {k})"
            )))
        }
    };
    let expect = |index: usize, angle: f64| {
        if c[index] == angle {
            Ok(())
        } else {
            Err(PlaneProblem::Angle(
                index,
                format!(
                    "C angle {} is {}°, but Isym {isym} needs {angle}° there",
                    index + 1,
                    c[index]
                ),
            ))
        }
    };
    match isym {
        0 => Ok((Symmetry::None, 0..=mc - 1)),
        1 => Ok((Symmetry::Rotational, 0..=0)),
        2 => {
            divisible(2)?;
            expect(mc / 2, 180.0)?;
            Ok((Symmetry::BilateralC0C180, 0..=mc / 2))
        }
        3 => {
            divisible(4)?;
            expect(mc / 4, 90.0)?;
            expect(3 * mc / 4, 270.0)?;
            Ok((Symmetry::BilateralC90C270, mc / 4..=3 * mc / 4))
        }
        _ => {
            divisible(4)?;
            expect(mc / 4, 90.0)?;
            Ok((Symmetry::Quadrant, 0..=mc / 4))
        }
    }
}

/// The one-field-per-line part of the file (lines 1–26).
struct Fields<'a> {
    lines: &'a [&'a str],
    next: usize,
    file: &'a str,
}

impl<'a> Fields<'a> {
    fn syntax(&self, line: usize, message: String) -> PhotometryError {
        PhotometryError::Syntax {
            file: self.file.to_string(),
            line,
            message,
        }
    }

    /// The next line (1-based number, text without trailing blanks).
    fn line(&mut self, what: &str) -> Result<(usize, &'a str), PhotometryError> {
        match self.lines.get(self.next) {
            Some(&text) => {
                self.next += 1;
                Ok((self.next, text.trim_end()))
            }
            None => Err(self.syntax(
                self.lines.len().max(1),
                format!(
                    "file ends early: expected {what} on line {}",
                    self.lines.len() + 1
                ),
            )),
        }
    }

    fn text(&mut self, what: &str) -> Result<String, PhotometryError> {
        Ok(self.line(what)?.1.trim().to_string())
    }

    fn number_at(&mut self, what: &str) -> Result<(usize, f64), PhotometryError> {
        let (line, text) = self.line(what)?;
        let text = text.trim();
        if text.is_empty() {
            return Err(self.syntax(line, format!("{what}: expected a number, found nothing")));
        }
        let value = super::parse_number_with_decimal_comma(text)
            .ok_or_else(|| self.syntax(line, format!("{what}: '{text}' is not a number")))?;
        if !value.is_finite() {
            return Err(self.syntax(line, format!("{what}: '{text}' is not a finite number")));
        }
        Ok((line, value))
    }

    fn number(&mut self, what: &str) -> Result<f64, PhotometryError> {
        Ok(self.number_at(what)?.1)
    }

    fn non_negative(&mut self, what: &str) -> Result<f64, PhotometryError> {
        let (line, value) = self.number_at(what)?;
        if value < 0.0 {
            return Err(self.syntax(line, format!("{what} is {value}: must not be negative")));
        }
        Ok(value)
    }

    fn integer_at(
        &mut self,
        what: &str,
        min: i64,
        max: i64,
    ) -> Result<(usize, i64), PhotometryError> {
        let (line, value) = self.number_at(what)?;
        if value.fract() != 0.0 {
            return Err(self.syntax(line, format!("{what}: {value} is not a whole number")));
        }
        if value < min as f64 || value > max as f64 {
            return Err(self.syntax(
                line,
                format!("{what} is {value}, must be between {min} and {max}"),
            ));
        }
        Ok((line, value as i64))
    }

    fn integer(&mut self, what: &str, min: i64, max: i64) -> Result<i64, PhotometryError> {
        Ok(self.integer_at(what, min, max)?.1)
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::tests::ies_file;
    use super::super::*;

    /// An EULUMDAT file: `isym`, the full C-angle list, the γ list, the stored planes in
    /// cd/klm, and the first lamp set (count, flux). Other fields are plausible constants.
    pub(in super::super) fn ldt_file(
        isym: u8,
        c_list: &[f64],
        gamma: &[f64],
        planes: &[Vec<f64>],
        lamps: i64,
        flux: f64,
    ) -> String {
        let mut s = String::new();
        let mut line = |x: &dyn std::fmt::Display| s.push_str(&format!("{x}\r\n"));
        line(&"Unit test company");
        line(&1);
        line(&isym);
        line(&c_list.len());
        line(&(if c_list.len() > 1 { c_list[1] } else { 0.0 }));
        line(&gamma.len());
        line(&(gamma[1] - gamma[0]));
        line(&"REPORT-1");
        line(&"Test luminaire");
        line(&"CAT-1");
        line(&"test.ldt");
        line(&"2024-01-01 / unit test");
        for v in [620, 620, 80, 600, 600, 0, 0, 0, 0] {
            line(&v);
        }
        line(&100);
        line(&80);
        line(&1);
        line(&0);
        line(&1);
        line(&lamps);
        line(&"LED");
        line(&flux);
        line(&"4000");
        line(&"80");
        line(&30);
        for k in 0..10 {
            line(&(0.5 + 0.04 * k as f64));
        }
        for c in c_list {
            line(c);
        }
        for g in gamma {
            line(g);
        }
        for plane in planes {
            for v in plane {
                line(v);
            }
        }
        s
    }

    fn every(step: f64, to: f64) -> Vec<f64> {
        (0..)
            .map(|k| k as f64 * step)
            .take_while(|&c| c <= to)
            .collect()
    }

    /// Planes (cd/klm) of a distribution with I(C) = I(360 − C) = I(180 − C): quadrant
    /// symmetric, varying with C, on a 30° C grid.
    fn quadrant_planes(gamma: &[f64]) -> Vec<Vec<f64>> {
        [0.0, 30.0, 60.0, 90.0]
            .iter()
            .map(|c: &f64| {
                gamma
                    .iter()
                    .map(|g| {
                        let gr = g.to_radians();
                        (300.0 + 50.0 * (2.0 * c.to_radians()).cos()) * gr.cos().max(0.0)
                            + 2.0 * gr.sin()
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn isym_forms_agree_with_each_other_and_with_ies() {
        let gamma = every(15.0, 180.0);
        let q = quadrant_planes(&gamma);
        let c_list = every(30.0, 330.0);
        // Full list of planes over C = 0, 30, …, 330 from the quadrant: 0 30 60 90 60 30 0 …
        let index = |c: usize| {
            let c = c % 180;
            (if c > 90 { 180 - c } else { c }) / 30
        };
        let full: Vec<Vec<f64>> = (0..12).map(|k| q[index(k * 30)].clone()).collect();
        let flux = 2500.0;
        let forms = [
            (0, full.clone()),
            (2, full[0..=6].to_vec()),
            (3, full[3..=9].to_vec()),
            (4, full[0..=3].to_vec()),
        ];
        let parsed: Vec<Photometry> = forms
            .iter()
            .map(|(isym, planes)| {
                from_eulumdat(
                    &ldt_file(*isym, &c_list, &gamma, planes, 1, flux),
                    &format!("isym{isym}.ldt"),
                )
                .unwrap_or_else(|e| panic!("Isym {isym}: {e}"))
            })
            .collect();
        // The same distribution as a quadrant IES file in cd (× 2.5 klm).
        let cd = |p: &Vec<f64>| p.iter().map(|v| v * flux / 1000.0).collect::<Vec<_>>();
        let ies = from_ies(
            &ies_file(
                &gamma,
                &[0.0, 30.0, 60.0, 90.0],
                &q.iter().map(cd).collect::<Vec<_>>(),
            ),
            "q.ies",
        )
        .unwrap();
        for k in 0..300 {
            let c = (k as f64 * 23.9) % 360.0;
            let g = (k as f64 * 7.1) % 180.0;
            let reference = ies.intensity(c, g);
            for p in &parsed {
                // Same values (up to the ×2.5 rounding) at the same angles.
                assert!(
                    (p.intensity(c, g) - reference).abs() <= 1e-12 * reference.max(1.0),
                    "{} at C = {c}, γ = {g}: {} vs {reference}",
                    p.file,
                    p.intensity(c, g)
                );
            }
        }
        for p in &parsed {
            assert!(
                (p.flux() - ies.flux()).abs() <= 1e-12 * ies.flux(),
                "{}",
                p.file
            );
            assert_eq!(p.lamp_lumens, Some(flux));
        }
        assert_eq!(parsed[3].symmetry, Symmetry::Quadrant);
        assert_eq!(parsed[2].symmetry, Symmetry::BilateralC90C270);
    }

    #[test]
    fn rotational_ldt_and_metadata() {
        let gamma = every(10.0, 90.0);
        let plane: Vec<f64> = gamma.iter().map(|g| 318.3 * g.to_radians().cos()).collect();
        let text = ldt_file(1, &[0.0], &gamma, &[plane], 2, 1000.0);
        let p = from_eulumdat(&text, "rot.ldt").unwrap();
        assert_eq!(p.symmetry, Symmetry::Rotational);
        assert_eq!(p.c_angles(), &[0.0]);
        assert!((p.intensity(77.0, 0.0) - 318.3).abs() < 1e-12);
        assert_eq!(p.intensity(0.0, 95.0), 0.0);
        assert_eq!(p.metadata.format, SourceFormat::Eulumdat);
        assert_eq!(
            p.metadata.manufacturer.as_deref(),
            Some("Unit test company")
        );
        assert_eq!(p.metadata.luminaire.as_deref(), Some("Test luminaire"));
        assert_eq!(p.metadata.catalogue.as_deref(), Some("CAT-1"));
        assert_eq!(p.metadata.lamp.as_deref(), Some("LED"));
        assert_eq!(p.metadata.input_watts, Some(30.0));
        assert_eq!(p.metadata.light_output_ratio, Some(0.8));
        assert_eq!(p.opening.length_m, 0.6);
        assert_eq!(p.opening.width_m, 0.6);
        // Total flux of the set, not per lamp: two lamps do not double it.
        assert_eq!(p.lamp_lumens, Some(1000.0));
    }

    #[test]
    fn conversion_factor_and_absolute_photometry() {
        let gamma = every(90.0, 180.0);
        let plane = vec![100.0, 20.0, 0.0];
        // Conversion factor 2 (line 24).
        let text = ldt_file(1, &[0.0], &gamma, std::slice::from_ref(&plane), 1, 3000.0);
        let mut lines: Vec<&str> = text.split("\r\n").collect();
        assert_eq!(lines[23], "1");
        lines[23] = "2,0";
        let p = from_eulumdat(&lines.join("\r\n"), "cf.ldt").unwrap();
        assert!((p.intensity(0.0, 0.0) - 100.0 * 2.0 * 3.0).abs() < 1e-12);
        // Absolute photometry: negative lamp count; the flux field is the luminaire's flux.
        let text = ldt_file(1, &[0.0], &gamma, &[plane], -1, 3000.0);
        let p = from_eulumdat(&text, "abs.ldt").unwrap();
        assert_eq!(p.lamp_lumens, None);
        assert!((p.intensity(0.0, 90.0) - 60.0).abs() < 1e-12);
    }

    #[test]
    fn second_lamp_set_does_not_scale() {
        let gamma = every(90.0, 180.0);
        let text = ldt_file(1, &[0.0], &gamma, &[vec![100.0, 20.0, 0.0]], 1, 2000.0);
        // Insert a second set after the first (lines 26a–f are lines 27–32).
        let mut lines: Vec<String> = text.split("\r\n").map(str::to_string).collect();
        lines[25] = "2".to_string();
        let second = ["3", "T5 alternative", "9000", "3000", "80", "60"];
        for (k, l) in second.iter().enumerate() {
            lines.insert(32 + k, l.to_string());
        }
        let p = from_eulumdat(&lines.join("\n"), "two.ldt").unwrap();
        assert!((p.intensity(0.0, 0.0) - 200.0).abs() < 1e-12);
        assert_eq!(p.lamp_lumens, Some(2000.0));
        assert!(p
            .metadata
            .keywords
            .iter()
            .any(|(k, v)| k == "LAMPSET2" && v.contains("T5 alternative")));
    }

    #[test]
    fn several_values_per_line_and_decimal_commas_are_accepted() {
        let gamma = every(45.0, 180.0);
        let text = ldt_file(
            1,
            &[0.0],
            &gamma,
            &[vec![100.0, 80.0, 20.0, 1.0, 0.0]],
            1,
            1e3,
        );
        let mut lines: Vec<String> = text.split("\r\n").map(str::to_string).collect();
        // Intensities (lines 49–53) on one line, one of them with a decimal comma.
        let joined = "100 80 20,5 1 0".to_string();
        lines.splice(48..53, [joined]);
        let p = from_eulumdat(&lines.join("\r\n"), "lenient.ldt").unwrap();
        assert!((p.intensity(0.0, 90.0) - 20.5).abs() < 1e-12);
        assert!((p.intensity(0.0, 22.5) - 90.0).abs() < 1e-12);
    }

    fn malformed_cases() -> Vec<(&'static str, String, usize, &'static str)> {
        let gamma = every(45.0, 180.0);
        let plane = vec![100.0, 80.0, 20.0, 1.0, 0.0];
        let good = ldt_file(1, &[0.0], &gamma, std::slice::from_ref(&plane), 1, 1000.0);
        let lines: Vec<String> = good.split("\r\n").map(str::to_string).collect();
        let n = lines.len();
        let edit = |k: usize, value: &str| {
            let mut l = lines.clone();
            l[k] = value.to_string();
            l.join("\n")
        };
        let truncate = |k: usize| lines[..k].join("\n");
        let full4 = vec![plane.clone(); 4];
        vec![
            ("empty", String::new(), 1, "empty"),
            ("Isym 5", edit(2, "5"), 3, "Isym"),
            ("Ityp text", edit(1, "point"), 2, "not a number"),
            ("negative Mc", edit(3, "-4"), 4, "Mc"),
            ("huge Ng", edit(5, "1000000"), 6, "Ng"),
            ("negative Dc", edit(4, "-15"), 5, "Dc"),
            ("NaN dimension", edit(15, "NaN"), 16, "finite"),
            ("empty numeric field", edit(21, ""), 22, "found nothing"),
            (
                "zero conversion factor",
                edit(23, "0"),
                24,
                "conversion factor",
            ),
            ("no lamp sets", edit(25, "0"), 26, "lamp sets"),
            ("zero lamps", edit(26, "0"), 27, "number of lamps"),
            ("zero lamp flux", edit(28, "0"), 29, "flux"),
            ("truncated header", truncate(20), 20, "line 21"),
            (
                "truncated intensities",
                truncate(n - 3),
                n - 3,
                "luminous intensities",
            ),
            ("extra value", format!("{good}5\r\n"), n, "extra"),
            ("negative intensity", edit(n - 3, "-1"), n - 2, "negative"),
            ("NaN intensity", edit(n - 3, "nan"), n - 2, "finite"),
            ("decreasing γ", edit(n - 8, "80"), n - 7, "non-decreasing"),
            ("γ beyond 180", edit(n - 7, "200"), n - 6, "outside"),
            ("first C not 0", edit(n - 12, "10"), n - 11, "first C angle"),
            (
                "Isym 4 without C90",
                ldt_file(4, &[0.0, 45.0, 100.0, 270.0], &gamma, &full4[..2], 1, 1e3),
                44,
                "needs 90",
            ),
            (
                "Isym 2 with odd Mc",
                ldt_file(2, &[0.0, 120.0, 240.0], &gamma, &full4[..2], 1, 1e3),
                4,
                "multiple of 2",
            ),
            (
                "Isym 3 wrong C270",
                ldt_file(3, &[0.0, 90.0, 180.0, 260.0], &gamma, &full4[..3], 1, 1e3),
                46,
                "needs 270",
            ),
            ("binary", "EULUMDAT\n\0\0\0".to_string(), 2, "NUL"),
        ]
    }

    #[test]
    fn malformed_files_fail_with_file_line_and_reason() {
        let cases = malformed_cases();
        assert!(cases.len() >= 20);
        for (what, text, line, word) in cases {
            let e = match from_eulumdat(&text, "bad.ldt") {
                Ok(_) => panic!("{what}: accepted"),
                Err(e) => e,
            };
            let message = e.to_string();
            assert_eq!(e.line(), Some(line), "{what}: {message}");
            assert!(
                message.starts_with(&format!("bad.ldt: line {line}: ")),
                "{what}: {message}"
            );
            assert!(message.contains(word), "{what}: '{word}' not in: {message}");
        }
    }
}
