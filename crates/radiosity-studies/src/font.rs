//! The bundled font for plot text and contact-sheet labels: DejaVu Sans (licence in
//! `assets/DejaVuSans.LICENSE`), so no system font library is needed.

use std::sync::OnceLock;

/// The font file.
pub static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Registers the bundled font with plotters as "sans-serif" (once per process).
pub fn register_font() -> Result<(), String> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, FONT)
            .is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("the bundled font could not be loaded".into())
    }
}
