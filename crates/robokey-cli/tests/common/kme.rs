//! The key servers' surroundings in tests: certificates made with rcgen (a CA, the servers'
//! certificate for 127.0.0.1, the applications' client certificates), `robokey kme` on
//! loopback, and curl — an HTTP client that is not robokey code — as the application.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};

use rcgen::{
    BasicConstraints, CertificateParams, CertifiedIssuer, DnType, ExtendedKeyUsagePurpose, IsCa,
    KeyPair,
};

use super::{Process, s, start};

/// The SAE ID of the controller's application (the ETSI master).
pub const CONTROLLER_SAE: &str = "controller-app";
/// The SAE ID of the robot's application (the ETSI slave).
pub const ROBOT_SAE: &str = "robot-app";

/// A certificate and its private key, as PEM files.
#[derive(Clone)]
pub struct Identity {
    pub cert: PathBuf,
    pub key: PathBuf,
}

/// The certificates of a test, in `dir`.
#[derive(Clone)]
pub struct Pki {
    /// The CA of the servers' and the applications' certificates.
    pub ca: PathBuf,
    /// The servers' certificate (127.0.0.1 and localhost).
    pub server: Identity,
    /// The controller application's client certificate (CN `controller-app`).
    pub controller_app: Identity,
    /// The robot application's client certificate (CN `robot-app`).
    pub robot_app: Identity,
    /// A client certificate of the right CA for another application (CN `eve-app`).
    pub other_app: Identity,
    /// A client certificate naming `controller-app`, from another CA.
    pub rogue_app: Identity,
}

impl Pki {
    pub fn new(dir: &Path) -> Self {
        let ca = authority("robokey test CA");
        let rogue = authority("someone else's CA");
        let write = |name: &str, pem: &str| {
            let path = dir.join(name);
            std::fs::write(&path, pem).unwrap();
            use std::os::unix::fs::PermissionsExt as _;
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600)).unwrap();
            path
        };
        let ca_path = write("ca.pem", &ca.pem());
        let issue = |cn: &str, issuer: &CertifiedIssuer<'static, KeyPair>, server: bool| {
            let by = if std::ptr::eq(issuer, &ca) {
                ""
            } else {
                "-rogue"
            };
            let key = KeyPair::generate().unwrap();
            let names = if server {
                vec!["127.0.0.1".to_owned(), "localhost".to_owned()]
            } else {
                Vec::new()
            };
            let mut params = CertificateParams::new(names).unwrap();
            params.distinguished_name.push(DnType::CommonName, cn);
            params.extended_key_usages = vec![if server {
                ExtendedKeyUsagePurpose::ServerAuth
            } else {
                ExtendedKeyUsagePurpose::ClientAuth
            }];
            let cert = params.signed_by(&key, issuer).unwrap();
            let file = format!("{cn}-{}{by}", if server { "server" } else { "client" });
            Identity {
                cert: write(&format!("{file}.pem"), &cert.pem()),
                key: write(&format!("{file}.key"), &key.serialize_pem()),
            }
        };
        let rogue_app = issue(CONTROLLER_SAE, &rogue, false);
        Self {
            ca: ca_path,
            server: issue("robokey kme", &ca, true),
            controller_app: issue(CONTROLLER_SAE, &ca, false),
            robot_app: issue(ROBOT_SAE, &ca, false),
            other_app: issue("eve-app", &ca, false),
            rogue_app,
        }
    }
}

/// A self-signed CA named `name`.
fn authority(name: &str) -> CertifiedIssuer<'static, KeyPair> {
    let mut params = CertificateParams::new(Vec::<String>::new()).unwrap();
    params.is_ca = IsCa::Ca(BasicConstraints::Unconstrained);
    params.distinguished_name.push(DnType::CommonName, name);
    CertifiedIssuer::self_signed(params, KeyPair::generate().unwrap()).unwrap()
}

/// A running `robokey kme`: its process, its base URL, and its log as it comes (read as it
/// is written, so that the server never waits on a full pipe).
pub struct Kme {
    pub process: Process,
    pub url: String,
    pub log: Arc<Mutex<String>>,
}

/// `robokey kme` on the store `store` for the application `sae` (whose peer is `peer`), on
/// a port of loopback the system chooses.
pub fn start_kme(pki: &Pki, store: &Path, pairing: &str, sae: &str, peer: &str) -> Kme {
    let mut process = start(&[
        "kme",
        "--store",
        &s(store),
        "--pairing",
        pairing,
        "--listen",
        "127.0.0.1:0",
        "--tls-cert",
        &s(&pki.server.cert),
        "--tls-key",
        &s(&pki.server.key),
        "--client-ca",
        &s(&pki.ca),
        "--sae-id",
        sae,
        "--peer-sae-id",
        peer,
    ]);
    let log = Arc::new(Mutex::new(String::new()));
    let mut stdout = process.child.stdout.take().expect("piped");
    std::thread::spawn({
        let log = Arc::clone(&log);
        move || {
            let mut line = [0_u8; 4096];
            while let Ok(n @ 1..) = std::io::Read::read(&mut stdout, &mut line) {
                log.lock()
                    .unwrap()
                    .push_str(&String::from_utf8_lossy(&line[..n]));
            }
        }
    });
    let url = format!("https://{}", process.address);
    Kme { process, url, log }
}

/// Both sides' servers, on the stores `dir/controller` and `dir/robot`: (the controller
/// side's, the robot side's).
pub fn start_pair(pki: &Pki, dir: &Path, pairing: &str) -> (Kme, Kme) {
    (
        start_kme(
            pki,
            &dir.join("controller"),
            pairing,
            CONTROLLER_SAE,
            ROBOT_SAE,
        ),
        start_kme(pki, &dir.join("robot"), pairing, ROBOT_SAE, CONTROLLER_SAE),
    )
}

/// What curl got: its exit code, the HTTP status (0 when none) and the body.
#[derive(Debug)]
pub struct Fetched {
    pub exit: i32,
    pub status: u16,
    pub body: String,
}

impl Fetched {
    /// The body as JSON (panics, naming the body, when it is not).
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("{e}: {self:?}"))
    }

    /// Asserts an answer of the standard's error container: HTTP `status` with a `message`
    /// that contains `says`.
    pub fn assert_error(&self, status: u16, says: &str) {
        assert_eq!(self.status, status, "{self:?}");
        let message = self.json()["message"]
            .as_str()
            .unwrap_or_default()
            .to_owned();
        assert!(message.contains(says), "not {says:?}: {self:?}");
    }
}

/// Whether curl is here; false only where CI=true is not set (CI must have it).
pub fn have_curl() -> bool {
    let found = Command::new("curl")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(
        found || std::env::var("CI").as_deref() != Ok("true"),
        "curl is missing: the key server's tests need an HTTP client that is not robokey code"
    );
    if !found {
        eprintln!("curl is missing: the key server is not tested with an ordinary client here");
    }
    found
}

/// `curl` as `client` (its certificate, or none), trusting the test CA: `method` on `url`
/// with a JSON `body` if given. At most 20 s.
pub fn curl(
    pki: &Pki,
    client: Option<&Identity>,
    method: &str,
    url: &str,
    body: Option<&str>,
) -> Fetched {
    let mut command = Command::new("curl");
    command.args([
        "-sS",
        "--max-time",
        "20",
        "--cacert",
        &s(&pki.ca),
        "-X",
        method,
    ]);
    command.args(["-w", "\n%{http_code}"]);
    if let Some(client) = client {
        command.args(["--cert", &s(&client.cert), "--key", &s(&client.key)]);
    }
    if let Some(body) = body {
        command.args([
            "-H",
            "Content-Type: application/json",
            "--data-binary",
            body,
        ]);
    }
    let out = command.arg(url).output().expect("curl runs");
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let (body, status) = text.rsplit_once('\n').unwrap_or(("", &text));
    Fetched {
        exit: out.status.code().unwrap_or(-1),
        status: status.trim().parse().unwrap_or(0),
        body: body.to_owned() + &String::from_utf8_lossy(&out.stderr),
    }
}
