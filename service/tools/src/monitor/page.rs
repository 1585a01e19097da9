//! The web page of `GET /`: static HTML ([`HTML`], `page.html`) and its script
//! ([`SCRIPT`], `page.js`, served at `/page.js`), built into the binary. No build step:
//! plain HTML, CSS and JavaScript that poll `/api/state` and `/api/points` and draw on
//! canvases.
//!
//! Stable element ids for a browser test: `#scope` (canvas of z and u), `#theta-scope`,
//! `#theta-norm`, `#verdict`, `#verdict-text`, `#connection`, `#run-state`, `#run-id`,
//! `#last-seq`, `#display-latency-ms` (sample time → first drawn, ms; its
//! `data-value-ms` attribute holds the unrounded value), `#flag-safe-state`,
//! `#flag-operator-safe-state`, `#flag-adaptation-frozen`, `#flag-open-loop`,
//! `#flag-plant-silent` (class `on` when set), `#tones`, `#tones-table`,
//! `#lat-{response,compute,wakeup,jitter}-{p50,p99,max,count}` (µs), `#counters`,
//! `#all-counters`, `#config`, `#controller`, `#rig-select`, the command buttons
//! `#freeze`, `#resume`, `#enter-safe`, `#leave-safe`, `#stop-run`, `#set-tunable` with
//! `#tunable-name` and `#tunable-value`, `#commands-note` (why they are disabled) and
//! `#command-result`.

/// The page.
pub const HTML: &str = include_str!("page.html");
/// Its script.
pub const SCRIPT: &str = include_str!("page.js");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_page_has_the_ids_a_test_reads_and_loads_its_script() {
        for id in [
            "scope",
            "theta-norm",
            "verdict",
            "freeze",
            "last-seq",
            "display-latency-ms",
            "commands-note",
            "config",
            "rig-select",
            "set-tunable",
            "tunable-value",
        ] {
            assert!(HTML.contains(&format!("id=\"{id}\"")), "#{id} missing");
        }
        assert!(HTML.contains("<script src=\"/page.js\">"));
        assert!(SCRIPT.contains("display-latency-ms"));
    }
}
