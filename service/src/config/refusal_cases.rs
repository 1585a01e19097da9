//! Table-driven refusal checks shared by the configuration's unit tests.

use super::ServiceConfig;

/// For each `(from, to, field)`: `from` occurs once in `base`; with it replaced by `to`
/// the file is refused, and the error starts with `<origin>: field '<field>'`.
pub(super) fn assert_refused_naming_fields(base: &str, origin: &str, cases: &[(&str, &str, &str)]) {
    for (from, to, field) in cases {
        assert_eq!(base.matches(from).count(), 1, "'{from}' must occur once");
        let text = base.replacen(from, to, 1);
        let m = ServiceConfig::parse(&text, origin)
            .err()
            .unwrap_or_else(|| panic!("accepted: {to}"))
            .to_string();
        assert!(
            m.starts_with(&format!("{origin}: field '{field}'")),
            "{to}: {m}"
        );
    }
}
