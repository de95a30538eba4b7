//! The real proxy binary as a child process: started on a fixed port and a given database,
//! killed with SIGKILL, restarted on the same port and database, its file size limit lowered
//! and raised from outside (`prlimit`).

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use penmesh_e2e::TestSession;

/// How long a started proxy may take to answer `/readyz` (a debug build on a loaded machine).
const START_DEADLINE: Duration = Duration::from_secs(30);

/// A proxy process.
#[derive(Debug)]
pub struct ProxyChild {
    child: Option<Child>,
    pub port: u16,
    pub database_url: String,
    args: Vec<String>,
    log: PathBuf,
    _dir: tempfile::TempDir,
    http: reqwest::Client,
}

impl Drop for ProxyChild {
    fn drop(&mut self) {
        self.kill();
    }
}

impl ProxyChild {
    /// Starts the proxy on a free port with `database_url` and the extra flags `args`.
    pub async fn start(database_url: &str, args: &[&str]) -> ProxyChild {
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let dir = tempfile::tempdir().unwrap();
        let mut proxy = ProxyChild {
            child: None,
            port,
            database_url: database_url.to_string(),
            args: args.iter().map(|a| a.to_string()).collect(),
            log: dir.path().join("proxy.log"),
            _dir: dir,
            http: reqwest::Client::builder().timeout(Duration::from_secs(15)).build().unwrap(),
        };
        proxy.spawn().await;
        proxy
    }

    async fn spawn(&mut self) {
        assert!(self.child.is_none(), "the proxy is running");
        // A write past the file size limit must fail with EFBIG (what SQLite sees on a full
        // disk) instead of killing the process with SIGXFSZ: a shell ignores the signal and
        // execs the proxy (same pid), and an ignored signal stays ignored across exec.
        let mut command = Command::new("/bin/sh");
        command
            .args(["-c", "trap '' XFSZ; exec \"$0\" \"$@\"", env!("CARGO_BIN_EXE_e2e-proxy")])
            .args(["--host", "127.0.0.1", "--port", &self.port.to_string()])
            .args(["--database-url", &self.database_url])
            .args(["--shutdown-grace-secs", "2"])
            .args(&self.args)
            .env("RUST_LOG", "warn")
            .stdin(Stdio::null())
            // Through pipes, which the file size limit does not cover, to a file of this
            // process: the log goes on while the proxy cannot write files.
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = command.spawn().expect("the proxy binary starts");
        let open = || std::fs::OpenOptions::new().create(true).append(true).open(&self.log);
        let (mut out, mut err) = (open().unwrap(), open().unwrap());
        let (mut stdout, mut stderr) = (child.stdout.take().unwrap(), child.stderr.take().unwrap());
        std::thread::spawn(move || std::io::copy(&mut stdout, &mut out));
        std::thread::spawn(move || std::io::copy(&mut stderr, &mut err));
        self.child = Some(child);
        self.wait_ready().await;
    }

    async fn wait_ready(&mut self) {
        let deadline = Instant::now() + START_DEADLINE;
        loop {
            if let Ok(r) = self.http.get(self.url("/readyz")).send().await
                && r.status() == 200
            {
                return;
            }
            if let Some(status) = self.child.as_mut().and_then(|c| c.try_wait().unwrap()) {
                panic!("the proxy exited with {status} while starting:\n{}", self.log_text());
            }
            assert!(Instant::now() < deadline, "the proxy is not ready:\n{}", self.log_text());
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }

    pub fn pid(&self) -> i32 {
        self.child.as_ref().expect("the proxy is running").id() as i32
    }

    pub fn url(&self, path: &str) -> String {
        format!("http://127.0.0.1:{}{path}", self.port)
    }

    /// SIGKILL, and waits for the process to be gone.
    pub fn kill(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }

    /// Starts the proxy again on the same port and database.
    pub async fn restart(&mut self) {
        self.kill();
        self.spawn().await;
    }

    /// Sets the soft limit on the size of any file the proxy writes (`None`: no limit).
    pub fn set_file_size_limit(&self, bytes: Option<u64>) {
        use rustix::process::{Pid, Resource, Rlimit, prlimit};
        let pid = Pid::from_raw(self.pid()).expect("a pid");
        prlimit(Some(pid), Resource::Fsize, Rlimit { current: bytes, maximum: None })
            .expect("prlimit on the proxy");
    }

    /// What the proxy has logged so far.
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }

    pub async fn create_session(&self) -> TestSession {
        let response = self.http.post(self.url("/v1/sessions")).send().await.unwrap();
        assert_eq!(response.status(), 201);
        let body: serde_json::Value = response.json().await.unwrap();
        TestSession::new(
            body["session"].as_str().unwrap().parse().unwrap(),
            body["token"].as_str().unwrap().to_string(),
        )
    }

    /// The value of a counter of `/metrics` (0 when it was never incremented).
    pub async fn counter(&self, name: &str) -> f64 {
        let text = self.http.get(self.url("/metrics")).send().await.unwrap().text().await.unwrap();
        text.lines()
            .filter(|line| line.split([' ', '{']).next() == Some(name))
            .filter_map(|line| line.rsplit(' ').next()?.parse::<f64>().ok())
            .sum()
    }

    pub fn http(&self) -> &reqwest::Client {
        &self.http
    }
}
