//! Users of the service: bearer tokens mapped to names and roles, read from a token file that
//! holds only SHA-256 hashes of the tokens. A presented token is hashed and compared with
//! every entry in constant time, so neither the file nor the timing gives a token away.
//!
//! File format, one user per line (blank lines and `#` comments ignored):
//! `NAME ROLE SHA256HEX`, ROLE `user` or `admin`, the hash of the token's bytes in hex
//! (`printf %s "$TOKEN" | sha256sum`).

use sha2::{Digest, Sha256};
use subtle::ConstantTimeEq;

/// A problem in a token file, with its line.
#[derive(Debug, thiserror::Error)]
pub enum UsersError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// A line is not `NAME ROLE SHA256HEX`.
    #[error("token file line {line}: {message}")]
    Line {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// No user at all: every request would be refused.
    #[error("the token file lists no user")]
    Empty,
}

/// One user.
#[derive(Debug, Clone)]
pub struct User {
    /// Name, as jobs record their owner.
    pub name: String,
    /// Admins see and cancel every job and read `/metrics`.
    pub admin: bool,
    hash: [u8; 32],
}

/// The users of a service.
#[derive(Debug, Clone)]
pub struct Users {
    users: Vec<User>,
}

/// SHA-256 of a token.
pub fn token_hash(token: &str) -> [u8; 32] {
    Sha256::digest(token.as_bytes()).into()
}

fn parse_hex(text: &str) -> Option<[u8; 32]> {
    if text.len() != 64 || !text.is_ascii() {
        return None;
    }
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&text[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(out)
}

impl Users {
    /// Reads a token file.
    pub fn load(path: &std::path::Path) -> Result<Users, UsersError> {
        let text = std::fs::read_to_string(path).map_err(|source| UsersError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Users::parse(&text)
    }

    /// Parses a token file's text.
    pub fn parse(text: &str) -> Result<Users, UsersError> {
        let mut users: Vec<User> = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line_no = n + 1;
            let content = line.split('#').next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let bad = |message: String| UsersError::Line {
                line: line_no,
                message,
            };
            let fields: Vec<&str> = content.split_whitespace().collect();
            let [name, role, hash] = fields[..] else {
                return Err(bad(format!(
                    "expected `NAME ROLE SHA256HEX`, found {} field(s)",
                    fields.len()
                )));
            };
            let admin = match role {
                "admin" => true,
                "user" => false,
                other => return Err(bad(format!("role `{other}` is neither `user` nor `admin`"))),
            };
            let hash = parse_hex(hash).ok_or_else(|| {
                bad("the hash must be 64 hex digits (SHA-256 of the token)".into())
            })?;
            if users.iter().any(|u| u.name == name) {
                return Err(bad(format!("user `{name}` is listed twice")));
            }
            if users.iter().any(|u| u.hash == hash) {
                return Err(bad("two users have the same token".into()));
            }
            users.push(User {
                name: name.to_string(),
                admin,
                hash,
            });
        }
        if users.is_empty() {
            return Err(UsersError::Empty);
        }
        Ok(Users { users })
    }

    /// The user whose token this is. Every entry is compared (in constant time), whichever
    /// matches, so the time taken says nothing about the tokens.
    pub fn authenticate(&self, token: &str) -> Option<&User> {
        let presented = token_hash(token);
        let mut found = None;
        for user in &self.users {
            if bool::from(user.hash.ct_eq(&presented)) {
                found = Some(user);
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hex(bytes: [u8; 32]) -> String {
        bytes.iter().map(|b| format!("{b:02x}")).collect()
    }

    #[test]
    fn tokens_map_to_users_by_hash() {
        let text = format!(
            "# users\nalice user {}\n\nops admin {}  # the operators\n",
            hex(token_hash("a-secret")),
            hex(token_hash("o-secret"))
        );
        let users = Users::parse(&text).unwrap();
        let alice = users.authenticate("a-secret").unwrap();
        assert_eq!((alice.name.as_str(), alice.admin), ("alice", false));
        assert!(users.authenticate("o-secret").unwrap().admin);
        assert!(users.authenticate("a-secre").is_none());
        assert!(users.authenticate("").is_none());
        // The known SHA-256 of "abc".
        assert_eq!(
            hex(token_hash("abc")),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn bad_files_name_their_line() {
        let h = hex(token_hash("x"));
        for (text, line) in [
            (
                format!("alice user {h}\nbob boss {}", hex(token_hash("y"))),
                2,
            ),
            ("alice user 1234".to_string(), 1),
            (format!("alice {h}"), 1),
            (format!("a user {h}\nb user {h}"), 2),
            (format!("a user {h}\na user {}", hex(token_hash("y"))), 2),
        ] {
            match Users::parse(&text) {
                Err(UsersError::Line { line: l, .. }) => assert_eq!(l, line, "{text}"),
                other => panic!("{text}: {other:?}"),
            }
        }
        assert!(matches!(Users::parse("# nobody\n"), Err(UsersError::Empty)));
    }
}
