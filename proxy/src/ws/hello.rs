//! A connection's `Hello` (the version, the resume list, the participant's key, the join) and
//! its participant's name (`Rename`, held to one a second).

use std::time::Duration;

use penmesh::protocol::{
    ErrorCode, Hello, MAX_NAME_CHARS, OLDEST_PROTOCOL_VERSION, PROTOCOL_VERSION, ServerMessage,
    Welcome, check_text, is_supported_version,
};
use tokio::time::Instant;

use super::close_code;
use super::connection::Connection;
use super::error::{ConnError, End};
use crate::events::{EventKind, SessionEvent};
use crate::identity::clean_name;
use crate::store::WriteOp;

/// At most one new name is stored per connection in this time (`Connection::on_rename`).
pub(super) const RENAME_INTERVAL: Duration = Duration::from_secs(1);

impl Connection {
    pub(super) async fn on_hello(&mut self, hello: Hello) -> Result<(), ConnError> {
        if !is_supported_version(hello.protocol) {
            return Err(ConnError::fatal(
                ErrorCode::Protocol,
                format!(
                    "protocol version {} is not supported; this proxy speaks \
                     {OLDEST_PROTOCOL_VERSION} to {PROTOCOL_VERSION}",
                    hello.protocol
                ),
                End::Close(close_code::PROTOCOL, "unsupported protocol".into()),
            ));
        }
        let max_resume = self.state.config.max_open_strokes;
        if hello.resume.len() > max_resume {
            // Each entry costs a query and perhaps a claim wait: refuse a long list outright.
            return Err(ConnError::fatal(
                ErrorCode::TooManyOpenStrokes,
                format!(
                    "hello.resume names {} strokes, more than the limit of {max_resume} open \
                     strokes per connection",
                    hello.resume.len()
                ),
                End::Close(close_code::POLICY, "resume list too long".into()),
            ));
        }
        let name = hello.name.as_deref();
        for (field, text) in [("hello.client", Some(hello.client.as_str())), ("hello.name", name)] {
            if let Some(Err(why)) = text.map(|t| check_text(t, MAX_NAME_CHARS)) {
                return Err(ConnError::refused(
                    ErrorCode::Malformed,
                    format!("{field} {why}"),
                    None,
                ));
            }
        }
        if let Some(key) = &hello.key {
            self.participant = crate::identity::participant_of(self.session, "hello.key", key)
                .map_err(|why| ConnError::refused(ErrorCode::Malformed, why, None))?;
        }
        self.hello = true;
        self.outgoing.version = hello.protocol;
        tracing::debug!(connection = self.id, client = %hello.client, "hello");
        let (resume, resent) = self.resume_strokes(hello.resume).await;
        self.send(ServerMessage::Welcome(Welcome {
            protocol: hello.protocol,
            session: self.session,
            participant: self.participant,
            resume,
        }));
        for (stroke, kept) in resent {
            self.send_retained(stroke, 0, &kept);
        }
        let (participant, session, connection) = (self.participant, self.session, self.presence);
        let asked = hello.name.as_deref().and_then(clean_name);
        let known = self.known_name(hello.key.is_some()).await;
        let name = (asked.clone().or_else(|| known.clone()))
            .or_else(|| clean_name(&hello.client))
            .unwrap_or_else(|| "guest".into());
        let mut ops = vec![WriteOp::Join {
            connection,
            participant,
            session,
            name: name.clone(),
            replica: self.state.claims.replica_key(),
        }];
        let mut events = vec![SessionEvent::from_connection(
            self.id,
            session,
            EventKind::Joined { participant, connection, name: name.clone() },
        )];
        // Another name than the participant's connections had: a rename, which the session
        // hears (a second connection's join is not news to it).
        if known.is_some_and(|known| known != name) {
            ops.push(WriteOp::Rename { participant, session, name: name.clone() });
            events.push(SessionEvent::from_connection(
                self.id,
                session,
                EventKind::Renamed { participant, name },
            ));
        }
        let joined = self.state.writer.write_with(ops, events).await;
        match joined {
            Ok(()) => self.joined = true,
            // Drawing goes on; the others do not see this participant in the list.
            Err(err) => {
                tracing::error!(connection = self.id, error = %err, "storing a participant failed")
            }
        }
        self.resync(None).await;
        Ok(())
    }

    /// The name the participant last went by in this session (an earlier connection's), which
    /// a hello without a name keeps: none for a participant without a key (a fresh one).
    async fn known_name(&self, has_key: bool) -> Option<String> {
        if !has_key {
            return None;
        }
        match self.state.store.participant_names(self.session).await {
            Ok(mut names) => names.remove(&self.participant),
            Err(err) => {
                tracing::warn!(connection = self.id, error = %err, "reading the participant's name failed");
                None
            }
        }
    }

    /// A new display name ([`clean_name`]): stored on the participant's presence rows and
    /// told to the others. Not answered: the client knows its name. At most one is stored per
    /// [`RENAME_INTERVAL`]: one asked for sooner waits for its turn, and a later one replaces
    /// it (a name typed letter by letter reaches the others as its last form, within a second).
    pub(super) async fn on_rename(&mut self, name: String) -> Result<(), ConnError> {
        check_text(&name, MAX_NAME_CHARS).map_err(|why| {
            ConnError::refused(ErrorCode::Malformed, format!("rename.name {why}"), None)
        })?;
        let Some(name) = clean_name(&name) else {
            return Err(ConnError::refused(
                ErrorCode::Malformed,
                "rename.name is empty once cleaned (control and bidirectional characters and a \
                 trailing \"(you)\" removed)",
                None,
            ));
        };
        if self.rename_due().is_some_and(|due| due > Instant::now()) {
            metrics::counter!("penmesh_renames_deferred_total").increment(1);
            self.pending_name = Some(name);
            return Ok(());
        }
        self.pending_name = None;
        self.store_name(name).await
    }

    /// When the next rename may be stored.
    pub(super) fn rename_due(&self) -> Option<Instant> {
        self.renamed_at.map(|at| at + RENAME_INTERVAL)
    }

    /// Stores the rename that waited for its turn, if any.
    pub(super) async fn store_pending_name(&mut self) {
        if let Some(name) = self.pending_name.take()
            && let Err(err) = self.store_name(name).await
        {
            self.fail(err);
        }
    }

    async fn store_name(&mut self, name: String) -> Result<(), ConnError> {
        self.renamed_at = Some(Instant::now());
        let (participant, session) = (self.participant, self.session);
        let event = SessionEvent::from_connection(
            self.id,
            session,
            EventKind::Renamed { participant, name: name.clone() },
        );
        let op = WriteOp::Rename { participant, session, name };
        if let Err(err) = self.state.writer.write_with(vec![op], vec![event]).await {
            return Err(ConnError::internal(
                "storing a new name",
                err,
                "the new name could not be stored; send it again",
                None,
            ));
        }
        Ok(())
    }
}
