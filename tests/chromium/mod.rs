//! A headless Chromium driven over the DevTools protocol on a pipe (`--remote-debugging-pipe`:
//! the browser reads commands from file descriptor 3 and writes answers and events to 4, as
//! NUL-terminated JSON): no driver package, no network port.
#![allow(dead_code)]

use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Write};
use std::os::fd::AsRawFd;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

/// How long one command may take (a page's load included).
const TIMEOUT: Duration = Duration::from_secs(120);

/// The browser: `GELENK_CHROMIUM` if set, else the first of Debian's and Google's usual paths.
pub fn find() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("GELENK_CHROMIUM") {
        return Some(PathBuf::from(path));
    }
    ["/usr/bin/chromium", "/usr/bin/chromium-browser", "/usr/bin/google-chrome"]
        .into_iter()
        .map(PathBuf::from)
        .find(|p| p.exists())
}

/// One browser with one page (tab), `width` × `height` CSS pixels at one device pixel each.
pub struct Page {
    child: Child,
    commands: std::io::PipeWriter,
    messages: Receiver<Value>,
    next_id: u64,
    session: String,
    /// Events received so far (console messages, exceptions, log entries, …).
    pub events: Vec<Value>,
    profile: PathBuf,
}

impl Page {
    /// Starts `chromium` headless with a fresh profile in `profile` (created, removed on drop).
    pub fn open(chromium: &Path, profile: &Path, width: u32, height: u32) -> Page {
        std::fs::create_dir_all(profile).unwrap();
        let (browser_reads, commands) = std::io::pipe().unwrap();
        let (answers, browser_writes) = std::io::pipe().unwrap();
        let (r, w) = (browser_reads.as_raw_fd(), browser_writes.as_raw_fd());
        let mut command = Command::new(chromium);
        command
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader",
                "--disable-quic",
                "--no-first-run",
                "--no-default-browser-check",
                "--disable-background-networking",
                "--disable-component-update",
                "--disable-sync",
                "--disable-extensions",
                "--remote-debugging-pipe",
            ])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(format!("--window-size={width},{height}"))
            .arg("about:blank")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        // SAFETY: only async-signal-safe calls (fcntl, dup2, close) between fork and exec. The
        // pipe ends are first copied above 10 so that moving them onto 3 and 4 cannot overwrite
        // one another, and dup2 clears close-on-exec on the copies at 3 and 4.
        unsafe {
            command.pre_exec(move || {
                let (high_r, high_w) = (libc::fcntl(r, libc::F_DUPFD, 10), libc::fcntl(w, libc::F_DUPFD, 10));
                if high_r < 0 || high_w < 0 || libc::dup2(high_r, 3) < 0 || libc::dup2(high_w, 4) < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                libc::close(high_r);
                libc::close(high_w);
                Ok(())
            });
        }
        let child = command.spawn().unwrap_or_else(|e| panic!("cannot start {}: {e}", chromium.display()));
        drop((browser_reads, browser_writes));
        let (sender, messages) = channel();
        std::thread::spawn(move || {
            let mut reader = BufReader::new(answers);
            let mut message = Vec::new();
            while reader.read_until(0, &mut message).is_ok_and(|n| n > 0) {
                if message.last() == Some(&0) {
                    message.pop();
                }
                if let Ok(value) = serde_json::from_slice::<Value>(&message) {
                    if sender.send(value).is_err() {
                        break;
                    }
                }
                message.clear();
            }
        });
        let mut page = Page {
            child,
            commands,
            messages,
            next_id: 0,
            session: String::new(),
            events: Vec::new(),
            profile: profile.to_path_buf(),
        };
        let target = page.browser_call("Target.createTarget", json!({ "url": "about:blank" }));
        let target = target["targetId"].as_str().unwrap().to_string();
        let attached =
            page.browser_call("Target.attachToTarget", json!({ "targetId": target, "flatten": true }));
        page.session = attached["sessionId"].as_str().unwrap().to_string();
        for domain in ["Page.enable", "Runtime.enable", "Log.enable"] {
            page.call(domain, json!({}));
        }
        page.call(
            "Emulation.setDeviceMetricsOverride",
            json!({ "width": width, "height": height, "deviceScaleFactor": 1, "mobile": false }),
        );
        page
    }

    fn send(&mut self, method: &str, params: Value, session: Option<String>) -> Value {
        self.next_id += 1;
        let id = self.next_id;
        let mut message = json!({ "id": id, "method": method, "params": params });
        if let Some(session) = session {
            message["sessionId"] = Value::String(session);
        }
        let mut bytes = serde_json::to_vec(&message).unwrap();
        bytes.push(0);
        self.commands.write_all(&bytes).unwrap();
        let deadline = Instant::now() + TIMEOUT;
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.messages.recv_timeout(left) {
                Ok(value) if value["id"] == id => {
                    if let Some(error) = value.get("error") {
                        panic!("{method}: {error}");
                    }
                    return value["result"].clone();
                }
                Ok(value) => {
                    if value.get("method").is_some() {
                        self.events.push(value);
                    }
                }
                Err(RecvTimeoutError::Timeout) => panic!("{method}: no answer in {TIMEOUT:?}"),
                Err(RecvTimeoutError::Disconnected) => panic!("{method}: the browser closed the pipe"),
            }
        }
    }

    fn browser_call(&mut self, method: &str, params: Value) -> Value {
        self.send(method, params, None)
    }

    /// A command to the page; its result.
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        let session = self.session.clone();
        self.send(method, params, Some(session))
    }

    /// Loads `url` and waits for its load event.
    pub fn navigate(&mut self, url: &str) {
        let seen = self.events.len();
        self.call("Page.navigate", json!({ "url": url }));
        let deadline = Instant::now() + TIMEOUT;
        while !self.events[seen..].iter().any(|e| e["method"] == "Page.loadEventFired") {
            let left = deadline.saturating_duration_since(Instant::now());
            match self.messages.recv_timeout(left) {
                Ok(value) if value.get("method").is_some() => self.events.push(value),
                Ok(_) => {}
                Err(_) => panic!("{url}: no load event in {TIMEOUT:?}"),
            }
        }
    }

    /// Evaluates a JavaScript expression in the page, awaiting a promise; its value as JSON.
    /// An exception is a panic with its text.
    pub fn eval(&mut self, expression: &str) -> Value {
        let result = self.call(
            "Runtime.evaluate",
            json!({ "expression": expression, "awaitPromise": true, "returnByValue": true }),
        );
        if let Some(exception) = result.get("exceptionDetails") {
            panic!("{expression}: {exception}");
        }
        result["result"]["value"].clone()
    }

    /// The bounding box of the first element that matches `selector`: (left, top, width,
    /// height), CSS pixels.
    pub fn rect(&mut self, selector: &str) -> (f64, f64, f64, f64) {
        let selector = serde_json::to_string(selector).unwrap();
        let r = self.eval(&format!(
            "(() => {{ const r = document.querySelector({selector}).getBoundingClientRect(); \
             return [r.left, r.top, r.width, r.height]; }})()"
        ));
        let r: Vec<f64> = r.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
        (r[0], r[1], r[2], r[3])
    }

    /// One mouse event at (x, y) CSS pixels: `kind` is `mouseMoved`, `mousePressed` or
    /// `mouseReleased`; `button` is `none`, `left` or `right` (held while moving).
    pub fn mouse(&mut self, kind: &str, (x, y): (f64, f64), button: &str) {
        let held = match (kind, button) {
            ("mouseReleased", _) => 0,
            (_, "left") => 1,
            (_, "right") => 2,
            _ => 0,
        };
        let clicks = if kind == "mouseMoved" { 0 } else { 1 };
        self.call(
            "Input.dispatchMouseEvent",
            json!({ "type": kind, "x": x, "y": y, "button": button, "buttons": held, "clickCount": clicks }),
        );
    }

    /// A left click at `at`.
    pub fn click(&mut self, at: (f64, f64)) {
        self.mouse("mouseMoved", at, "none");
        self.mouse("mousePressed", at, "left");
        self.mouse("mouseReleased", at, "left");
    }

    /// Presses `button` at `from`, moves to `to` in ten steps and releases it there.
    pub fn drag(&mut self, from: (f64, f64), to: (f64, f64), button: &str) {
        self.mouse("mouseMoved", from, "none");
        self.mouse("mousePressed", from, button);
        for i in 1..=10 {
            let s = i as f64 / 10.0;
            self.mouse("mouseMoved", (from.0 + s * (to.0 - from.0), from.1 + s * (to.1 - from.1)), button);
        }
        self.mouse("mouseReleased", to, button);
    }

    /// A turn of the mouse wheel at `at` (`delta_y` > 0: towards the user).
    pub fn wheel(&mut self, at: (f64, f64), delta_y: f64) {
        self.call(
            "Input.dispatchMouseEvent",
            json!({ "type": "mouseWheel", "x": at.0, "y": at.1, "deltaX": 0, "deltaY": delta_y }),
        );
    }

    /// Presses and releases a key: `key` as in KeyboardEvent.key (" " for the space bar,
    /// "ArrowDown"), `code` as in KeyboardEvent.code, `key_code` the Windows virtual key code.
    pub fn key(&mut self, key: &str, code: &str, key_code: u32) {
        let printable = key.chars().count() == 1;
        let down = if printable { "keyDown" } else { "rawKeyDown" };
        let mut event = json!({ "type": down, "key": key, "code": code, "windowsVirtualKeyCode": key_code });
        if printable {
            event["text"] = Value::String(key.to_string());
        }
        self.call("Input.dispatchKeyEvent", event.clone());
        event["type"] = Value::String("keyUp".to_string());
        event.as_object_mut().unwrap().remove("text");
        self.call("Input.dispatchKeyEvent", event);
    }

    /// Waits `milliseconds` of the page's time (its animation frames go on meanwhile).
    pub fn wait(&mut self, milliseconds: u32) {
        self.eval(&format!("new Promise((done) => setTimeout(() => done(true), {milliseconds}))"));
    }

    /// A screenshot of the viewport: (width, height, RGBA pixels) and the PNG file's bytes.
    pub fn screenshot(&mut self) -> (Image, Vec<u8>) {
        use base64::Engine as _;
        let shot = self.call("Page.captureScreenshot", json!({ "format": "png" }));
        let png_bytes =
            base64::engine::general_purpose::STANDARD.decode(shot["data"].as_str().unwrap()).unwrap();
        let mut reader = png::Decoder::new(&png_bytes[..]).read_info().unwrap();
        let mut buffer = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buffer).unwrap();
        let channels = info.color_type.samples();
        let rgba = buffer[..info.buffer_size()]
            .chunks_exact(channels)
            .flat_map(|p| [p[0], p[1], p[2], if channels == 4 { p[3] } else { 255 }])
            .collect();
        (Image { width: info.width, height: info.height, rgba }, png_bytes)
    }

    /// Console errors, uncaught exceptions and error log entries seen so far, as text.
    pub fn errors(&self) -> Vec<String> {
        self.events
            .iter()
            .filter(|e| {
                let p = &e["params"];
                match e["method"].as_str() {
                    Some("Runtime.exceptionThrown") => true,
                    Some("Runtime.consoleAPICalled") => p["type"] == "error" || p["type"] == "assert",
                    Some("Log.entryAdded") => p["entry"]["level"] == "error",
                    _ => false,
                }
            })
            .map(|e| e["params"].to_string())
            .collect()
    }
}

impl Drop for Page {
    fn drop(&mut self) {
        // Closed by command, so that the browser ends its own processes; killed if it has not
        // ended within 10 s.
        self.next_id += 1;
        let close = json!({ "id": self.next_id, "method": "Browser.close" });
        let mut bytes = serde_json::to_vec(&close).unwrap();
        bytes.push(0);
        let _ = self.commands.write_all(&bytes);
        let deadline = Instant::now() + Duration::from_secs(10);
        while matches!(self.child.try_wait(), Ok(None)) && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.profile);
    }
}

/// An RGBA image.
pub struct Image {
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Rows of RGBA pixels, top first.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The pixel at column `x`, row `y`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let k = 4 * (y * self.width + x) as usize;
        [self.rgba[k], self.rgba[k + 1], self.rgba[k + 2], self.rgba[k + 3]]
    }

    /// The pixels for which `keep` holds: their count, centroid (x, y) and bounding box
    /// (min x, min y, max x, max y), in pixels.
    pub fn region(&self, keep: impl Fn([u8; 4]) -> bool) -> Option<Region> {
        let (mut n, mut sx, mut sy) = (0u64, 0.0, 0.0);
        let mut bounds = (u32::MAX, u32::MAX, 0, 0);
        for y in 0..self.height {
            for x in 0..self.width {
                if keep(self.pixel(x, y)) {
                    n += 1;
                    sx += x as f64 + 0.5;
                    sy += y as f64 + 0.5;
                    bounds = (bounds.0.min(x), bounds.1.min(y), bounds.2.max(x), bounds.3.max(y));
                }
            }
        }
        (n > 0).then(|| Region { pixels: n, centroid: (sx / n as f64, sy / n as f64), bounds })
    }
}

/// Pixels of an image that pass a test.
#[derive(Debug)]
pub struct Region {
    /// How many.
    pub pixels: u64,
    /// Their mean position (px; pixel centres at +0.5).
    pub centroid: (f64, f64),
    /// Their bounding box (min x, min y, max x, max y), px.
    pub bounds: (u32, u32, u32, u32),
}
