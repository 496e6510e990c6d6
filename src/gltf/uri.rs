//! Buffer URIs: schemes, percent-escapes and `data:` URIs.

use std::path::PathBuf;

/// Whether `uri` starts with a URL scheme (`http:`, `file:`, ...). One-letter schemes are
/// taken for Windows drive letters.
pub(super) fn has_scheme(uri: &str) -> bool {
    match uri.split_once(':') {
        Some((scheme, _)) => {
            scheme.len() > 1
                && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
                && scheme
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        }
        None => false,
    }
}

/// Decodes `%XX` escapes; malformed escapes are kept as they are.
fn percent_decode_bytes(s: &str) -> Vec<u8> {
    percent_encoding::percent_decode_str(s).collect()
}

/// A relative URI as a path (percent-escapes decoded, so `..%2F` is `../`).
pub(super) fn percent_decode(uri: &str) -> PathBuf {
    PathBuf::from(
        percent_encoding::percent_decode_str(uri)
            .decode_utf8_lossy()
            .into_owned(),
    )
}

/// Decodes the part of a data URI after `data:`.
pub(super) fn decode_data_uri(data: &str) -> std::result::Result<Vec<u8>, String> {
    let Some((header, payload)) = data.split_once(',') else {
        return Err("no ',' before the data".to_owned());
    };
    if header.ends_with(";base64") {
        decode_base64(payload)
    } else {
        Ok(percent_decode_bytes(payload))
    }
}

/// Decodes standard or URL-safe base64, with or without padding (bits past the last byte
/// are ignored, as decoders commonly do).
pub(super) fn decode_base64(s: &str) -> std::result::Result<Vec<u8>, String> {
    use base64::engine::{general_purpose as gp, DecodePaddingMode, GeneralPurpose};
    let config = gp::GeneralPurposeConfig::new()
        .with_decode_padding_mode(DecodePaddingMode::Indifferent)
        .with_decode_allow_trailing_bits(true);
    let standard = GeneralPurpose::new(&base64::alphabet::STANDARD, config);
    let url_safe = GeneralPurpose::new(&base64::alphabet::URL_SAFE, config);
    base64::Engine::decode(&standard, s)
        .or_else(|e| base64::Engine::decode(&url_safe, s).map_err(|_| e))
        .map_err(|e| format!("invalid base64: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips() {
        assert_eq!(decode_base64("").unwrap(), b"");
        assert_eq!(decode_base64("Zg==").unwrap(), b"f");
        assert_eq!(decode_base64("Zm8=").unwrap(), b"fo");
        assert_eq!(decode_base64("Zm9v").unwrap(), b"foo");
        assert_eq!(decode_base64("Zm9vYmFy").unwrap(), b"foobar");
        assert_eq!(decode_base64("AP8A/w").unwrap(), [0, 255, 0, 255]);
        assert!(decode_base64("Zm9v!").is_err());
        assert!(decode_base64("Zm9vY").is_err());
    }

    #[test]
    fn uris() {
        assert!(has_scheme("http://example.com/a.bin"));
        assert!(!has_scheme("C:/models/a.bin"));
        assert!(!has_scheme("models/a.bin"));
        assert_eq!(percent_decode_bytes("a%20b%2"), b"a b%2");
        assert_eq!(decode_data_uri("text/plain,a%41").unwrap(), b"aA");
    }
}
