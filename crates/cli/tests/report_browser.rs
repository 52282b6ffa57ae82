//! `report.html` in a real browser: Debian's headless Chromium opens the page `demo` wrote,
//! from disk and offline; the test fails on a console message, an image that does not load,
//! or a reference to the network, and keeps a screenshot of the whole page
//! (`report-screenshot.png` in cargo's test temp folder, path printed).

#[path = "../../../tests/support/paths.rs"]
mod paths;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Debian's package path (`apt-get install chromium`; `.ci/run` installs it).
const CHROMIUM: &str = "/usr/bin/chromium";
const SHIPPED_MODEL: &str = "models/envision4d-synth-tiny.safetensors";

fn repo(path: &str) -> PathBuf {
    paths::manifest_dir().join("../..").join(path)
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Headless Chromium on `page` with `extra` flags; console messages go to stderr.
fn chromium(page: &Path, extra: &[&str]) -> Output {
    assert!(
        Path::new(CHROMIUM).exists(),
        "{CHROMIUM} is missing: apt-get install -y chromium (.ci/run does)"
    );
    Command::new(CHROMIUM)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--enable-logging=stderr",
            "--v=0",
            // The report must not need the network: none is allowed.
            "--proxy-server=127.0.0.1:9",
            "--virtual-time-budget=10000",
        ])
        .args(extra)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs")
}

/// What the harness logs itself, to show that console capture works.
const MARKER: &str = "HARNESS_MARKER";

/// Console lines (`INFO:CONSOLE`, errors of the page's own) in Chromium's stderr, but the
/// harness's marker.
fn console_lines(o: &Output) -> Vec<String> {
    String::from_utf8_lossy(&o.stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE") && !l.contains(MARKER))
        .map(str::to_owned)
        .collect()
}

/// A harness page beside the report: loads it in a frame and, once every image has loaded
/// or failed, writes how many images there are and which did not decode.
const HARNESS: &str = r#"<!DOCTYPE html><html><body>
<iframe id="f" src="report.html" style="width:1400px;height:2000px"></iframe>
<pre id="result">pending</pre>
<script>
console.log('HARNESS_MARKER');
document.getElementById('f').addEventListener('load', () => {
  const d = document.getElementById('f').contentDocument;
  const imgs = Array.from(d.images);
  const broken = imgs.filter(i => !i.complete || i.naturalWidth === 0).map(i => i.getAttribute('src'));
  document.getElementById('result').textContent =
    'images=' + imgs.length + ' broken=' + JSON.stringify(broken) + ' title=' + d.title;
});
</script></body></html>"#;

/// Guards the report a user opens: every image loads in a real browser, the page logs
/// nothing to the console, names no network address and has no script; the demo's one clip
/// is shown as strips (ground truth, model, both image baselines, depth, mask, motion).
#[test]
fn the_demo_report_loads_in_headless_chromium() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("demo");
    let o = Command::new(env!("CARGO_BIN_EXE_envision4d"))
        .args(["demo", "--out", out.to_str().unwrap(), "--checkpoint"])
        .arg(repo(SHIPPED_MODEL))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let page = out.join("report.html");
    let html = std::fs::read_to_string(&page).unwrap();
    for banned in ["http://", "https://", "<script", "//cdn"] {
        assert!(!html.contains(banned), "report.html contains {banned}");
    }
    for column in [
        "ground truth",
        "model",
        "copy-last",
        "static+cv",
        "model depth",
        "true dynamic mask",
    ] {
        assert!(
            html.contains(&format!("<th>{column}</th>")),
            "no {column} column"
        );
    }

    let harness = out.join("browser-check.html");
    std::fs::write(&harness, HARNESS).unwrap();
    let check = chromium(&harness, &["--allow-file-access-from-files", "--dump-dom"]);
    assert!(check.status.success(), "{}", text(&check));
    let dom = String::from_utf8_lossy(&check.stdout);
    let result = dom
        .split("<pre id=\"result\">")
        .nth(1)
        .and_then(|r| r.split("</pre>").next())
        .unwrap_or_else(|| panic!("no result in the harness DOM:\n{dom}"));
    let images: usize = result
        .strip_prefix("images=")
        .and_then(|r| r.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("the harness did not run: {result}"));
    // T_f future frames x (truth, 3 methods, depth, mask), the motion panel, 2 plots.
    let metrics: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("metrics.json")).unwrap()).unwrap();
    let future = metrics["future_frames"].as_u64().unwrap() as usize;
    assert_eq!(images, future * 6 + 1 + 2, "{result}");
    assert!(
        result.contains("broken=[]"),
        "images that did not load: {result}"
    );
    // Console capture works (the harness's own line is seen), and the report adds nothing.
    assert!(
        String::from_utf8_lossy(&check.stderr).contains(MARKER),
        "console messages are not captured: {}",
        text(&check)
    );
    assert!(
        console_lines(&check).is_empty(),
        "{:?}",
        console_lines(&check)
    );

    // The harness can fail: a missing image is reported by name.
    let gone = html
        .split("src=\"")
        .nth(1)
        .and_then(|r| r.split('"').next())
        .unwrap()
        .to_owned();
    std::fs::rename(out.join(&gone), out.join("moved.png")).unwrap();
    let check = chromium(&harness, &["--allow-file-access-from-files", "--dump-dom"]);
    let dom = String::from_utf8_lossy(&check.stdout);
    assert!(
        dom.contains(&format!("broken=[&quot;{gone}&quot;]"))
            || dom.contains(&format!("broken=[\"{gone}\"]")),
        "{dom}"
    );
    std::fs::rename(out.join("moved.png"), out.join(&gone)).unwrap();

    let shot = Path::new(env!("CARGO_TARGET_TMPDIR")).join("report-screenshot.png");
    let _ = std::fs::remove_file(&shot);
    let arg = format!("--screenshot={}", shot.display());
    let o = chromium(&page, &[&arg, "--window-size=1400,3200"]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(console_lines(&o).is_empty(), "{:?}", console_lines(&o));
    let img = image::open(&shot).expect("the screenshot decodes");
    assert_eq!((img.width(), img.height()), (1400, 3200));
    eprintln!("screenshot: {}", shot.display());
}
