//! docs/results.md holds tables the code makes: this fails when one of them
//! is no longer what the code makes, naming it.

#[test]
fn docs_results_md_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/results.md");
    let doc = std::fs::read_to_string(path).expect("docs/results.md exists");
    let tables = lab::results::tables().expect("the tables render");
    let stale = lab::results::stale(&doc, &tables);
    assert!(
        stale.is_empty(),
        "docs/results.md: {} no longer what the code makes; run `cargo run --release -p lab -- results` \
         and commit the file",
        stale.join(", ")
    );
}
