//! The web page at `/` and the frame pictures behind it: the real `mpm serve` with users,
//! driven over HTTP (the PNG route) and from headless Chromium over the DevTools protocol
//! (load the page, give the token, submit an invalid scene and a valid one, watch it
//! finish, open its picture). `MPM_SCREENSHOTS=1` writes docs/web-jobs.png and
//! docs/web-job.png. Without a Chromium binary (`chromium` on the PATH or `MPM_CHROMIUM`) the
//! browser test says so and passes.

mod cdp;
use crate::common;

use common::*;
use reqwest::blocking::RequestBuilder;
use serde_json::{Value, json};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

const ALICE: &str = "alice-web-secret";
const BOB: &str = "bob-web-secret";

/// `mpm serve` with the users alice and bob, killed when dropped.
struct Server {
    _child: Process,
    url: String,
}

impl Server {
    fn start(dir: &Path) -> Server {
        let hex = |t: &str| -> String {
            mpm_service::token_hash(t)
                .iter()
                .map(|b| format!("{b:02x}"))
                .collect()
        };
        let tokens = dir.join("tokens");
        std::fs::write(
            &tokens,
            format!("alice user {}\nbob user {}\n", hex(ALICE), hex(BOB)),
        )
        .unwrap();
        let (child, url) = serve(
            Command::new(env!("CARGO_BIN_EXE_mpm"))
                .args(["serve", "--listen", "127.0.0.1:0", "--data"])
                .arg(dir.join("data"))
                .arg("--tokens")
                .arg(&tokens)
                .env_remove("RUST_LOG")
                .stderr(std::fs::File::create(dir.join("serve.log")).unwrap()),
        );
        Server {
            _child: Process(child),
            url,
        }
    }
}

/// The vibrating bar, short: 0.02 s, 4 frames.
fn small_bar() -> Value {
    let mut s = bar_json();
    s["solver"]["end_time"] = json!(0.02);
    s["output"]["frames"] = json!(4);
    s
}

fn send(r: RequestBuilder, token: &str) -> (u16, String, Vec<u8>) {
    let r = r.bearer_auth(token).send().unwrap();
    let status = r.status().as_u16();
    let kind = r
        .headers()
        .get("content-type")
        .map(|v| v.to_str().unwrap().to_string())
        .unwrap_or_default();
    (status, kind, r.bytes().unwrap().to_vec())
}

fn submit(url: &str, token: &str, scene: &Value) -> String {
    let (status, _, body) = send(
        http_client(60).post(format!("{url}/v1/jobs")).json(scene),
        token,
    );
    assert_eq!(status, 202, "{}", String::from_utf8_lossy(&body));
    let v: Value = serde_json::from_slice(&body).unwrap();
    v["id"].as_str().unwrap().to_string()
}

fn wait_final(url: &str, token: &str, id: &str) -> Value {
    let start = Instant::now();
    loop {
        let (_, _, body) = send(http_client(60).get(format!("{url}/v1/jobs/{id}")), token);
        let j: Value = serde_json::from_slice(&body).unwrap();
        if matches!(
            j["status"].as_str(),
            Some("succeeded" | "failed" | "cancelled")
        ) {
            return j;
        }
        assert!(start.elapsed() < Duration::from_secs(120), "{j}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

const PNG_MAGIC: &[u8] = b"\x89PNG\r\n\x1a\n";

#[test]
fn frame_pictures_are_pngs_for_their_owner_and_json_errors_otherwise() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path());
    let url = &server.url;
    let c = http_client(60);
    let bar = submit(url, ALICE, &small_bar());
    let mut cube: Value =
        serde_json::from_str(&std::fs::read_to_string(example("cube-drop.json")).unwrap()).unwrap();
    cube["solver"]["end_time"] = json!(0.002);
    cube["domain"]["cell_size"] = json!(0.0625);
    cube["output"]["frames"] = json!(1);
    let cube = submit(url, ALICE, &cube);
    assert_eq!(wait_final(url, ALICE, &bar)["status"], "succeeded");
    assert_eq!(wait_final(url, ALICE, &cube)["status"], "succeeded");

    let get = |path: &str, token: &str| send(c.get(format!("{url}{path}")), token);
    let error_code = |body: &[u8]| -> String {
        let v: Value = serde_json::from_slice(body)
            .unwrap_or_else(|_| panic!("not a JSON error: {}", String::from_utf8_lossy(body)));
        v["error"]["code"].as_str().unwrap_or("").to_string()
    };

    // Every frame, counted from either end, any stored field and component.
    for path in [
        format!("/v1/jobs/{bar}/frames/0"),
        format!("/v1/jobs/{bar}/frames/-1.png"),
        format!("/v1/jobs/{bar}/frames/2?field=v&component=1"),
        format!("/v1/jobs/{bar}/frames/4.png?field=stress"),
        // A 3D store, seen along z.
        format!("/v1/jobs/{cube}/frames/0?field=v&component=2"),
    ] {
        let (status, kind, body) = get(&path, ALICE);
        assert_eq!(status, 200, "{path}: {}", String::from_utf8_lossy(&body));
        assert_eq!(kind, "image/png", "{path}");
        assert!(body.starts_with(PNG_MAGIC), "{path}: not a PNG");
    }

    // Bad requests: JSON errors, the right status, never a crash.
    for (path, status, code) in [
        (format!("/v1/jobs/{bar}/frames/5"), 422, "cannot_render"),
        (format!("/v1/jobs/{bar}/frames/-6"), 422, "cannot_render"),
        (format!("/v1/jobs/{bar}/frames/abc"), 400, "bad_frame"),
        (
            format!("/v1/jobs/{bar}/frames/99999999999999999999"),
            400,
            "bad_frame",
        ),
        (
            format!("/v1/jobs/{bar}/frames/0?field=nope"),
            422,
            "cannot_render",
        ),
        (
            format!("/v1/jobs/{bar}/frames/0?field=../../x"),
            422,
            "cannot_render",
        ),
        (
            format!("/v1/jobs/{bar}/frames/0?field=v&component=7"),
            422,
            "cannot_render",
        ),
        (
            format!("/v1/jobs/{bar}/frames/0?component=-1"),
            400,
            "bad_frame",
        ),
        (
            format!("/v1/jobs/{cube}/frames/0?field=v&component=3"),
            422,
            "cannot_render",
        ),
        (
            "/v1/jobs/00000000-0000-0000-0000-000000000000/frames/0".to_string(),
            404,
            "not_found",
        ),
        ("/v1/jobs/not-a-job/frames/0".to_string(), 404, "not_found"),
    ] {
        let (got, _, body) = get(&path, ALICE);
        assert_eq!(got, status, "{path}: {}", String::from_utf8_lossy(&body));
        assert_eq!(error_code(&body), code, "{path}");
    }
    // The reason names the field; the server's folders are not named.
    let (_, _, body) = get(&format!("/v1/jobs/{cube}/frames/0?field=nope"), ALICE);
    let text = String::from_utf8_lossy(&body);
    assert!(text.contains("field `nope`"), "{text}");
    assert!(!text.contains(&dir.path().display().to_string()), "{text}");

    // Another user's job is as unknown as a missing one; no token is a 401.
    let (status, _, body) = get(&format!("/v1/jobs/{bar}/frames/0"), BOB);
    assert_eq!((status, error_code(&body).as_str()), (404, "not_found"));
    let r = c
        .get(format!("{url}/v1/jobs/{bar}/frames/0"))
        .send()
        .unwrap();
    assert_eq!(r.status(), 401);

    // The scene route: the owner's scene, 404 for another user.
    let (status, _, body) = get(&format!("/v1/jobs/{bar}/scene"), ALICE);
    assert_eq!(status, 200);
    let scene: Value = serde_json::from_slice(&body).unwrap();
    assert_eq!(scene["name"], "vibrating-bar");
    assert_eq!(get(&format!("/v1/jobs/{bar}/scene"), BOB).0, 404);

    // The page's files need no token and carry a content security policy.
    for (path, kind) in [
        ("/", "text/html"),
        ("/app.js", "text/javascript"),
        ("/style.css", "text/css"),
    ] {
        let r = c.get(format!("{url}{path}")).send().unwrap();
        assert_eq!(r.status(), 200, "{path}");
        let headers = r.headers();
        assert!(headers["content-type"].to_str().unwrap().starts_with(kind));
        assert!(
            headers["content-security-policy"]
                .to_str()
                .unwrap()
                .contains("script-src 'self'")
        );
    }
}

#[test]
fn the_page_submits_a_scene_follows_it_and_shows_its_picture() {
    let Some(chromium) = cdp::find_chromium() else {
        println!("SKIPPED: no chromium binary (install the Debian package `chromium`)");
        return;
    };
    let start = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(dir.path());
    let url = server.url.clone();
    // Three resolutions of the bar through the API, so the job page's error-against-run-time
    // plot has a study to show.
    let mut base = bar_json();
    base["solver"]["end_time"] = json!(0.1);
    base["output"]["frames"] = json!(10);
    for h in [0.1, 0.025] {
        let mut s = base.clone();
        s["domain"]["cell_size"] = json!(h);
        submit(&url, ALICE, &s);
    }

    let browser = cdp::Browser::start(&chromium);
    let mut page = browser.page();
    page.call(
        "Emulation.setDeviceMetricsOverride",
        json!({"width": 1400, "height": 1000, "deviceScaleFactor": 1, "mobile": false}),
    );
    page.call("Page.enable", json!({}));
    page.call("Page.navigate", json!({"url": format!("{url}/")}));
    // Without a token the list cannot load and the page says what is missing.
    page.wait_for(
        "document.getElementById('notice')?.textContent.includes('token')",
        30,
        "the page asking for a token",
    );
    // Any script error or content-security-policy violation from here on fails the test
    // (the page changes views by its URL's hash, so this window stays).
    page.eval(
        "window.__problems = [];
         window.addEventListener('error', e => __problems.push('error: ' + e.message));
         window.addEventListener('unhandledrejection', e => __problems.push('rejection: ' + e.reason));
         document.addEventListener('securitypolicyviolation',
           e => __problems.push('csp: ' + e.violatedDirective + ' ' + e.blockedURI)); true",
    );
    page.eval(&format!(
        "document.getElementById('token').value = '{ALICE}';
         document.getElementById('token-form').requestSubmit(); true"
    ));
    page.wait_for(
        "document.querySelectorAll('#jobs tbody tr').length >= 2",
        30,
        "the job list with the two jobs submitted over the API",
    );

    // An invalid scene pasted: the problem is shown at its JSON path.
    let mut invalid = small_bar();
    invalid["materials"]["bar"]["poisson_ratio"] = json!(0.7);
    page.eval("location.hash = '#/submit'; true");
    page.eval(&format!(
        "document.getElementById('scene-text').value = {};
         document.getElementById('submit-form').requestSubmit(); true",
        serde_json::to_string(&invalid.to_string()).unwrap()
    ));
    let shown = page.wait_for(
        "!document.getElementById('submit-errors').hidden &&
         [...document.querySelectorAll('#submit-problems li')].map(li => li.textContent).join('\\n')",
        30,
        "the validation problems",
    );
    assert!(
        shown
            .as_str()
            .unwrap()
            .contains("materials.bar.poisson_ratio"),
        "{shown}"
    );
    assert!(
        page.eval("document.querySelector('.problem-path').textContent")
            == "materials.bar.poisson_ratio"
    );

    // Text that is not JSON: a problem at `$`.
    page.eval(
        "document.getElementById('scene-text').value = '{\"name\": ';
         document.getElementById('submit-form').requestSubmit(); true",
    );
    page.wait_for(
        "document.querySelector('.problem-path')?.textContent === '$'",
        30,
        "the problem of text that is not JSON at `$`",
    );

    // A valid scene uploaded as a file, then submitted: the page moves to the new job.
    let mut scene = base.clone();
    scene["domain"]["cell_size"] = json!(0.05);
    let file = write_scene(dir.path(), "bar.json", &scene);
    let document = page.call("DOM.getDocument", json!({}));
    let input = page.call(
        "DOM.querySelector",
        json!({"nodeId": document["root"]["nodeId"], "selector": "#scene-file"}),
    );
    page.call(
        "DOM.setFileInputFiles",
        json!({"nodeId": input["nodeId"], "files": [file.display().to_string()]}),
    );
    page.wait_for(
        "document.getElementById('scene-text').value.includes('vibrating-bar')",
        10,
        "the uploaded file in the text area",
    );
    page.eval("document.getElementById('submit-form').requestSubmit(); true");
    let id = page.wait_for(
        "(location.hash.match(/^#\\/jobs\\/(.+)$/) || [])[1]",
        30,
        "the job page of the submitted scene",
    );
    let id = id.as_str().unwrap().to_string();

    // The job list follows it to the end.
    page.eval("location.hash = '#/'; true");
    page.wait_for(
        &format!(
            "document.querySelector('#jobs tr[data-id=\"{id}\"]')?.dataset.status === 'succeeded'"
        ),
        120,
        "the submitted job to finish in the list",
    );
    page.wait_for(
        "[...document.querySelectorAll('#jobs tr')].filter(r => r.dataset.status === 'succeeded').length >= 3",
        120,
        "every job to finish",
    );
    screenshot(&mut page, "web-jobs.png");

    // Its page: metrics with the error against the reference, the stability diagnostics,
    // the scene, the picture of its last frame, and the study plot.
    page.eval(&format!("location.hash = '#/jobs/{id}'; true"));
    page.wait_for(
        "(() => { const i = document.getElementById('frame'); return i.complete && i.naturalWidth > 0; })()",
        60,
        "the frame picture",
    );
    let width = page.eval("document.getElementById('frame').naturalWidth");
    assert!(width.as_u64().unwrap() >= 720, "{width}");
    let metrics = page.eval("document.getElementById('job-metrics').textContent");
    assert!(
        metrics.as_str().unwrap().contains("error kind"),
        "{metrics}"
    );
    let stability = page.eval("document.getElementById('job-stability').textContent");
    assert!(
        stability.as_str().unwrap().contains("energy drift"),
        "{stability}"
    );
    let scene_text = page.eval("document.getElementById('job-scene').textContent");
    assert!(scene_text.as_str().unwrap().contains("\"vibrating-bar\""));
    page.wait_for(
        "document.querySelectorAll('#study circle.point').length >= 3 && document.querySelector('#study circle.this')",
        30,
        "the error-against-run-time plot with three jobs",
    );
    // Another frame and field through the controls.
    page.eval(
        "(() => { const s = document.getElementById('frame-index'); s.value = 0;
         s.dispatchEvent(new Event('change')); return true; })()",
    );
    page.wait_for(
        "document.getElementById('frame').complete && document.getElementById('frame').naturalWidth > 0 && document.getElementById('frame-label').textContent.startsWith('0 of')",
        60,
        "frame 0",
    );
    let frame_src = page.eval("document.getElementById('frame').src");
    assert!(
        frame_src.as_str().unwrap().starts_with("blob:"),
        "{frame_src}"
    );
    page.eval(
        "(() => { const s = document.getElementById('frame-index'); s.value = s.max;
         s.dispatchEvent(new Event('change')); return true; })()",
    );
    std::thread::sleep(Duration::from_millis(500));
    page.wait_for(
        "document.getElementById('frame').complete && document.getElementById('frame').naturalWidth > 0",
        60,
        "the last frame again",
    );
    screenshot(&mut page, "web-job.png");

    // A longer job's page follows its progress live (the events stream; the page does not
    // poll), and its cancel button stops it.
    let mut long = base.clone();
    long["solver"]["end_time"] = json!(20.0);
    long["output"]["frames"] = json!(2);
    let long = submit(&url, ALICE, &long);
    page.eval(&format!("location.hash = '#/jobs/{long}'; true"));
    page.wait_for(
        "document.getElementById('job-status').textContent === 'running' &&
         document.getElementById('job-progress').value > 0",
        60,
        "live progress of the running job",
    );
    let before = page.eval("document.getElementById('job-progress').value");
    page.wait_for(
        &format!("document.getElementById('job-progress').value > {before}"),
        30,
        "the progress bar to move",
    );
    page.eval("document.getElementById('job-cancel').click(); true");
    page.wait_for(
        "document.getElementById('job-status').textContent === 'cancelled'",
        30,
        "the job cancelled from its page",
    );
    assert_eq!(wait_final(&url, ALICE, &long)["status"], "cancelled");
    let problems = page.eval("window.__problems");
    assert_eq!(
        problems,
        json!([]),
        "the page's script errors or policy violations"
    );
    println!("browser test: {:.1} s", start.elapsed().as_secs_f64());
}

/// Writes the viewport to docs/NAME when `MPM_SCREENSHOTS=1`.
fn screenshot(page: &mut cdp::Page, name: &str) {
    if std::env::var("MPM_SCREENSHOTS").as_deref() != Ok("1") {
        return;
    }
    let png = page.screenshot();
    assert!(png.starts_with(PNG_MAGIC));
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../docs")
        .join(name);
    std::fs::write(&path, png).unwrap();
    println!("wrote {}", path.display());
}
