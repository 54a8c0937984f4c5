//! The README's library examples are the examples' own code, not copies that drift: each
//! example's lines between `// README: begin` and `// README: end` are one of README.md's code
//! blocks, verbatim (the examples compile and run under `cargo test`; the README's blocks
//! besides as doc tests).

/// The code blocks of `markdown` (the lines between a fence line starting with ``` and the next).
fn code_blocks(markdown: &str) -> Vec<String> {
    let mut blocks = Vec::new();
    let mut current: Option<Vec<&str>> = None;
    for line in markdown.lines() {
        match (&mut current, line.starts_with("```")) {
            (None, true) => current = Some(Vec::new()),
            (Some(lines), true) => {
                blocks.push(lines.join("\n"));
                current = None;
            }
            (Some(lines), false) => lines.push(line),
            (None, false) => {}
        }
    }
    blocks
}

#[test]
fn the_readme_shows_each_example_verbatim() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let readme = std::fs::read_to_string(root.join("README.md")).unwrap();
    let blocks = code_blocks(&readme);
    for example in [
        "hanging_cloth",
        "cloth_newton",
        "solid_from_surface",
        "finite_difference_user_energy",
        "fluid_dam_break",
    ] {
        let path = root.join(format!("examples/{example}.rs"));
        let text = std::fs::read_to_string(&path).unwrap();
        let shown: Vec<&str> = text
            .lines()
            .skip_while(|l| *l != "// README: begin")
            .skip(1)
            .take_while(|l| *l != "// README: end")
            .collect();
        assert!(shown.len() > 10, "{}: no README part", path.display());
        let shown = shown.join("\n");
        assert!(
            blocks.contains(&shown),
            "README.md has no code block equal to the README part of {}:\n{shown}",
            path.display()
        );
        assert!(
            readme.contains(&format!("examples/{example}.rs")),
            "README.md names examples/{example}.rs"
        );
    }
}
