//! Table-driven refusal checks shared by the configuration's unit tests.

use super::ServiceConfig;

/// For each case of the refusal-case file `cases` (`tests/fixtures/refusals/`,
/// [`rig_scenario::refusal_cases`]): `from` occurs once in `base`; with it replaced by `to`
/// the file is refused, and the error starts with `<origin>: field '<field>'`.
pub(super) fn assert_refused_naming_fields(base: &str, origin: &str, cases: &str) {
    for c in rig_scenario::refusal_cases::parse(cases).unwrap() {
        assert_eq!(
            base.matches(&c.from).count(),
            1,
            "'{}' must occur once",
            c.from
        );
        let m = ServiceConfig::parse(&c.edit(base).unwrap(), origin)
            .err()
            .unwrap_or_else(|| panic!("accepted: {}", c.to))
            .to_string();
        assert!(
            m.starts_with(&format!("{origin}: field '{}'", c.field)),
            "{}: {m}",
            c.to
        );
    }
}
