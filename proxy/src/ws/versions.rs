//! Which protocol version a message belongs to, checked in one place: a connection speaks its
//! hello's version and nothing later (`docs/protocol.md`).

use penmesh::protocol::{ClientMessage, ErrorCode, is_supported_version};

use super::connection::Connection;
use super::error::ConnError;

impl Connection {
    /// Whether `msg` is of this connection's version (the one its `hello` named), the one
    /// place versions are checked: a binary frame carries that version in its first byte
    /// (`frame_version`), and a message or field a later version brought
    /// ([`ClientMessage::introduced_in`]) is `unknown_message`, as a variant index the version
    /// lacks is. Before the hello, its own frame must carry the version it names.
    pub(super) fn speaks(
        &self,
        frame_version: Option<u16>,
        msg: &ClientMessage,
    ) -> Result<(), ConnError> {
        let version = match msg {
            ClientMessage::Hello(hello) if !self.hello => {
                return match frame_version {
                    Some(framed)
                        if framed != hello.protocol && is_supported_version(hello.protocol) =>
                    {
                        Err(ConnError::refused(
                            ErrorCode::Protocol,
                            format!(
                                "hello.protocol is {} but its frame is of version {framed}: \
                                 every binary frame carries the connection's version",
                                hello.protocol
                            ),
                            None,
                        ))
                    }
                    _ => Ok(()),
                };
            }
            _ if !self.hello => return Ok(()),
            _ => self.outgoing.version,
        };
        if let Some(framed) = frame_version.filter(|&framed| framed != version) {
            return Err(ConnError::refused(
                ErrorCode::UnknownMessage,
                format!(
                    "a frame of version {framed} on a connection of version {version} (its \
                     hello): every binary frame carries the connection's version"
                ),
                None,
            ));
        }
        let (since, what) = msg.introduced_in();
        if since > version {
            return Err(ConnError::refused(
                ErrorCode::UnknownMessage,
                format!(
                    "{what} is of protocol version {since}; this connection speaks version \
                     {version} (its hello)"
                ),
                None,
            ));
        }
        Ok(())
    }
}
