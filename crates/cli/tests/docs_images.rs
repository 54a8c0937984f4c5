//! The documentation's pictures are made by `scripts/docs-images.sh`, never by hand: every PNG under
//! docs/ and every picture README.md or a docs/ page shows is one the script writes, so that
//! running it leaves no stale image behind.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The targets of Markdown images `![alt](target.png)` in `text`.
fn image_links(text: &str) -> Vec<String> {
    let mut links = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("![") {
        rest = &rest[start + 2..];
        let Some(close) = rest.find("](") else { break };
        let after = &rest[close + 2..];
        let Some(end) = after.find(')') else { break };
        let target = &after[..end];
        if target.ends_with(".png") {
            links.push(target.to_string());
        }
        rest = &after[end..];
    }
    links
}

#[test]
fn every_documentation_image_is_made_by_the_script() {
    let root = root();
    let script = std::fs::read_to_string(root.join("scripts/docs-images.sh")).unwrap();
    // The images the script places: `place SRC docs/NAME.png`.
    let made: Vec<&str> = script
        .lines()
        .filter_map(|l| l.trim().strip_prefix("place "))
        .filter_map(|l| l.split_whitespace().nth(1))
        .collect();
    assert!(made.contains(&"docs/preview-cloth-40.png"), "{made:?}");

    let mut pages = vec![root.join("README.md")];
    let mut images = Vec::new();
    for entry in std::fs::read_dir(root.join("docs")).unwrap() {
        let path = entry.unwrap().path();
        match path.extension().and_then(|e| e.to_str()) {
            Some("md") => pages.push(path),
            Some("png") => images.push(format!(
                "docs/{}",
                path.file_name().unwrap().to_str().unwrap()
            )),
            _ => {}
        }
    }
    for image in &images {
        assert!(
            made.contains(&image.as_str()),
            "{image} is not made by scripts/docs-images.sh"
        );
    }
    for page in &pages {
        let text = std::fs::read_to_string(page).unwrap();
        let dir = if page.ends_with("README.md") {
            ""
        } else {
            "docs/"
        };
        for link in image_links(&text) {
            let path = format!("{dir}{link}");
            assert!(
                made.contains(&path.as_str()),
                "{} shows {link}, which scripts/docs-images.sh does not make",
                page.display()
            );
            assert!(root.join(&path).is_file(), "{path} is missing");
        }
    }
}

#[test]
fn image_links_are_found() {
    assert_eq!(
        image_links("a ![x](docs/a.png) b ![y](b.png) [not](c.png) ![z](d.svg)"),
        ["docs/a.png", "b.png"]
    );
}
