//! docs/estimators.md shows the parameter table of every estimator in the lineup as its spec
//! makes it, so the documentation cannot drift from the code. `CVTRACE_BLESS=1 cargo test --test
//! estimator_docs` rewrites the tables in place.
use std::path::Path;

#[test]
fn the_parameter_tables_in_the_docs_are_the_specs() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/estimators.md");
    let mut text = std::fs::read_to_string(&path).unwrap();
    let bless = std::env::var_os("CVTRACE_BLESS").is_some();
    let mut stale = Vec::new();
    for spec in cvtrace_lineup::registry().specs() {
        let want = spec.markdown();
        let start = format!("<!-- parameters of {}:", spec.name);
        let end = format!("<!-- end of the parameters of {} -->\n", spec.name);
        let (Some(a), Some(b)) = (text.find(&start), text.find(&end)) else {
            panic!("docs/estimators.md has no parameter table of `{}`; add one with the lines\n{want}", spec.name);
        };
        let range = a..b + end.len();
        if text[range.clone()] != want {
            stale.push(spec.name);
            if bless {
                text.replace_range(range, &want);
            }
        }
    }
    if bless {
        std::fs::write(&path, &text).unwrap();
    } else {
        assert!(stale.is_empty(), "docs/estimators.md: the parameter tables of {stale:?} differ from the specs; run CVTRACE_BLESS=1 cargo test --test estimator_docs");
    }
}
