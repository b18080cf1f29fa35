//! The report's 3-D view in a real browser: a run of the built-in capture writes `report.html`; the page
//! alone (copied into an empty folder: no PNGs, no network) is opened in headless Chromium, which must
//! run its script without a console message, draw the final mesh (`data-view3d="ok"`) and show it — the
//! screenshot holds thousands of the viewer's colours, which nothing else on the page has without the PNGs —
//! and, with the support colouring chosen, colour the mesh by it (`data-view3d-colour="support"`).
//!
//! Needs `chromium` (Debian's package; `$NLOS_CHROMIUM` names another binary); CI installs it.

use std::path::Path;
use std::process::{Command, ExitCode, Output};

mod common;
use common::{FAST, fixture, scratch};

fn chromium(browser: &Path, args: &[&str], page: &Path) -> Output {
    Command::new(browser)
        .args(["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--no-first-run"])
        // WebGL without a GPU: ANGLE on SwiftShader, the software rasteriser Chromium ships.
        .args(["--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"])
        .args(["--virtual-time-budget=15000", "--enable-logging=stderr", "--v=0"])
        .args(args)
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium runs")
}

#[test]
fn report_html_shows_the_meshes_in_headless_chromium() {
    let Some(browser) = nlos_testdata::tool("NLOS_CHROMIUM", &["chromium", "chromium-browser", "google-chrome"]) else {
        return;
    };
    let (capture, truth) = (fixture("capture.hdf5"), fixture("truth.obj"));
    let run = scratch("view-run");
    let args = [
        "nlos",
        "reconstruct",
        capture.to_str().expect("utf8"),
        "--out",
        run.to_str().expect("utf8"),
        "--gt",
        truth.to_str().expect("utf8"),
        "--quiet",
    ];
    let code = nlos_cli::run(args.iter().chain(FAST.iter()));
    assert_eq!(code, ExitCode::SUCCESS);
    let html = std::fs::read_to_string(run.join("report.html")).expect("report.html");
    assert!(!html.contains("http://") && !html.contains("https://"), "the page must not need the network");
    let alone = scratch("view-alone");
    let page = alone.join("report.html");
    std::fs::write(&page, &html).expect("copy");

    let dom = chromium(&browser, &["--dump-dom"], &page);
    let (stdout, stderr) = (String::from_utf8_lossy(&dom.stdout), String::from_utf8_lossy(&dom.stderr));
    assert!(dom.status.success(), "chromium failed: {stderr}");
    let console: Vec<&str> = stderr.lines().filter(|l| l.contains(":CONSOLE")).collect();
    assert!(console.is_empty(), "console messages: {console:#?}");
    assert!(stdout.contains("data-view3d=\"ok\""), "the viewer did not draw: {:?}", stdout.find("data-view3d"));
    assert!(stdout.contains("data-view3d-colour=\"depth\""), "the page opens coloured by depth");

    // The same page with "support" chosen: the final mesh is coloured by how much of its light the data
    // confirm (the run wrote it, so the page must offer it).
    let by_support = html.replacen("value=\"depth\" checked", "value=\"depth\"", 1).replacen(
        "value=\"support\"",
        "value=\"support\" checked",
        1,
    );
    assert!(by_support.contains("value=\"support\" checked"), "the page offers no support colouring");
    let support_page = alone.join("support.html");
    std::fs::write(&support_page, &by_support).expect("copy");
    let dom = chromium(&browser, &["--dump-dom"], &support_page);
    let (stdout, stderr) = (String::from_utf8_lossy(&dom.stdout), String::from_utf8_lossy(&dom.stderr));
    assert!(dom.status.success(), "chromium failed: {stderr}");
    assert!(
        stdout.contains("data-view3d-colour=\"support\""),
        "the viewer did not colour by support: {:?}",
        stdout.find("data-view3d-colour")
    );

    let shot = alone.join("shot.png");
    let arg = format!("--screenshot={}", shot.display());
    let o = chromium(&browser, &["--window-size=1400,2600", &arg], &page);
    assert!(o.status.success(), "chromium failed: {}", String::from_utf8_lossy(&o.stderr));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&shot).expect("screenshot")));
    let mut reader = decoder.read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png frame");
    let channels = info.color_type.samples();
    // The page is black text on white and grey rules; the viewer's viridis colours are saturated.
    let coloured = buf[..info.buffer_size()]
        .chunks(channels)
        .filter(|px| {
            let (lo, hi) = (px[..3].iter().min().copied().unwrap_or(0), px[..3].iter().max().copied().unwrap_or(0));
            hi - lo > 60
        })
        .count();
    assert!(coloured > 5000, "only {coloured} coloured pixels: the mesh is not on screen");
}
