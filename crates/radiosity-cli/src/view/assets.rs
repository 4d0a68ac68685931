//! The page and its assets, embedded in the binary: the server reads no files.
//!
//! three.js is vendored unmodified from its npm package (`three` 0.187.0, MIT licence; see
//! `assets/view/VERSION` and `assets/view/THREE_LICENSE`): `build/three.module.js`, the
//! `build/three.core.js` it imports, and `examples/jsm/controls/OrbitControls.js`. The page
//! maps the bare specifier `three` to `/assets/three.module.js` with an import map.

/// One embedded file, served at `/assets/<name>` (the page itself at `/`).
pub struct Asset {
    /// Exact name in the URL.
    pub name: &'static str,
    /// `Content-Type` header value.
    pub content_type: &'static str,
    /// The file's bytes.
    pub bytes: &'static [u8],
}

const JS: &str = "text/javascript; charset=utf-8";

/// The page served at `/`.
pub const INDEX: Asset = Asset {
    name: "index.html",
    content_type: "text/html; charset=utf-8",
    bytes: include_bytes!("../../assets/view/index.html"),
};

/// Every file served under `/assets/`, by exact name.
pub const ASSETS: &[Asset] = &[
    Asset {
        name: "viewer.js",
        content_type: JS,
        bytes: include_bytes!("../../assets/view/viewer.js"),
    },
    Asset {
        name: "style.css",
        content_type: "text/css; charset=utf-8",
        bytes: include_bytes!("../../assets/view/style.css"),
    },
    Asset {
        name: "three.module.js",
        content_type: JS,
        bytes: include_bytes!("../../assets/view/three.module.js"),
    },
    Asset {
        name: "three.core.js",
        content_type: JS,
        bytes: include_bytes!("../../assets/view/three.core.js"),
    },
    Asset {
        name: "OrbitControls.js",
        content_type: JS,
        bytes: include_bytes!("../../assets/view/OrbitControls.js"),
    },
    Asset {
        name: "THREE_LICENSE",
        content_type: "text/plain; charset=utf-8",
        bytes: include_bytes!("../../assets/view/THREE_LICENSE"),
    },
    Asset {
        name: "VERSION",
        content_type: "text/plain; charset=utf-8",
        bytes: include_bytes!("../../assets/view/VERSION"),
    },
];

/// The asset named exactly `name`, if any.
pub fn asset(name: &str) -> Option<&'static Asset> {
    ASSETS.iter().find(|a| a.name == name)
}

/// The page's inline import map, exactly as in `index.html`, and the SHA-256 (base64) the
/// Content-Security-Policy allows it by. Changing one means changing both: a test checks
/// that the page holds this text, and the hash is
/// `printf %s "$IMPORT_MAP" | openssl dgst -sha256 -binary | base64`.
#[cfg(test)]
pub const IMPORT_MAP: &str = r#"{"imports":{"three":"/assets/three.module.js"}}"#;

/// SHA-256 of [`IMPORT_MAP`], base64, for the page's Content-Security-Policy.
pub const IMPORT_MAP_SHA256: &str = "oexVBXlzXdweqyT5QNgHJMBYrr7Ngn/RhQGsij5aRi4=";

/// The page's Content-Security-Policy: scripts, styles, data and connections only from this
/// server (plus the import map by its hash); no frames, no forms, no plug-ins.
pub fn content_security_policy() -> String {
    format!(
        "default-src 'none'; script-src 'self' 'sha256-{IMPORT_MAP_SHA256}'; \
         style-src 'self'; connect-src 'self'; img-src 'self' data:; \
         base-uri 'none'; form-action 'none'; frame-ancestors 'none'"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_holds_the_hashed_import_map() {
        let page = std::str::from_utf8(INDEX.bytes).unwrap();
        let inline = format!(r#"<script type="importmap">{IMPORT_MAP}</script>"#);
        assert!(
            page.contains(&inline),
            "index.html's import map differs from IMPORT_MAP"
        );
        assert_eq!(
            page.matches("<script").count(),
            2,
            "one import map, one module"
        );
    }

    #[test]
    fn names_are_unique_and_plain() {
        for (i, a) in ASSETS.iter().enumerate() {
            assert!(a
                .name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b == b'.' || b == b'_'));
            assert!(!a.name.contains(".."));
            assert!(ASSETS[..i].iter().all(|b| b.name != a.name));
            assert!(!a.bytes.is_empty(), "{} is empty", a.name);
        }
    }

    #[test]
    fn vendored_three_is_the_noted_version() {
        let version = std::str::from_utf8(asset("VERSION").unwrap().bytes).unwrap();
        let core = std::str::from_utf8(asset("three.core.js").unwrap().bytes).unwrap();
        // three.js states its revision in the core build: `const REVISION = '187';`.
        let revision = version
            .lines()
            .find_map(|l| l.strip_prefix("revision: "))
            .expect("VERSION names the revision");
        assert!(core.contains(&format!("const REVISION = '{revision}';")));
        let licence = std::str::from_utf8(asset("THREE_LICENSE").unwrap().bytes).unwrap();
        assert!(licence.starts_with("The MIT License"));
    }
}
