//! Failures injected into the writer's transactions, for the tests of its failure paths.

use std::sync::{Arc, Mutex};

use uuid::Uuid;

use super::{WriteOp, WriteRequest};

/// What an injected fault does to the transaction it hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fault {
    /// The transaction fails before `COMMIT`: nothing of it is stored.
    Fail,
    /// `COMMIT` succeeds, then the writer is told it failed (the connection dropped while the
    /// reply was on its way).
    FailAfterCommit,
}

/// Failures injected into the writer's transactions, for the tests of its failure paths. The
/// proxy never sets any outside tests ([`crate::Application::build_with_faults`]).
#[derive(Debug, Default)]
pub struct CommitFaults {
    state: Mutex<FaultState>,
}

#[derive(Debug, Default)]
struct FaultState {
    /// Transactions begun so far (group commits and retries alike).
    transactions: u64,
    rules: Vec<FaultRule>,
}

#[derive(Debug)]
struct FaultRule {
    target: FaultTarget,
    fault: Fault,
    /// How many more transactions it hits.
    remaining: u32,
}

#[derive(Debug)]
enum FaultTarget {
    /// The transaction the writer begins `k`th (1-based).
    Transaction(u64),
    /// Any transaction holding an append of `stroke` that holds sample `seq`.
    Append { stroke: Uuid, seq: u64 },
    /// Any transaction holding the begin of `stroke`.
    Begin { stroke: Uuid },
    /// Any transaction taking back or bringing back `stroke`.
    Removal { stroke: Uuid },
}

impl CommitFaults {
    pub fn new() -> Arc<CommitFaults> {
        Arc::new(CommitFaults::default())
    }

    /// The `k`th transaction from now (1: the next one; retries count) gets `fault`.
    pub fn fail_transaction(&self, k: u64, fault: Fault) {
        let mut state = self.state.lock().expect("faults lock");
        let target = FaultTarget::Transaction(state.transactions + k);
        state.rules.push(FaultRule { target, fault, remaining: 1 });
    }

    /// The next `times` transactions that hold an append of `stroke` holding sample `seq` get
    /// `fault`.
    pub fn fail_append(&self, stroke: Uuid, seq: u64, fault: Fault, times: u32) {
        let rule =
            FaultRule { target: FaultTarget::Append { stroke, seq }, fault, remaining: times };
        self.state.lock().expect("faults lock").rules.push(rule);
    }

    /// The next `times` transactions that hold the begin of `stroke` get `fault`.
    pub fn fail_begin(&self, stroke: Uuid, fault: Fault, times: u32) {
        let rule = FaultRule { target: FaultTarget::Begin { stroke }, fault, remaining: times };
        self.state.lock().expect("faults lock").rules.push(rule);
    }

    /// The next `times` transactions that take back or bring back `stroke` get `fault`.
    pub fn fail_removal(&self, stroke: Uuid, fault: Fault, times: u32) {
        let rule = FaultRule { target: FaultTarget::Removal { stroke }, fault, remaining: times };
        self.state.lock().expect("faults lock").rules.push(rule);
    }

    /// Removes every fault not yet spent.
    pub fn clear(&self) {
        self.state.lock().expect("faults lock").rules.clear();
    }

    /// Counts a transaction of `requests` and says which fault, if any, hits it.
    pub(super) fn hit(&self, requests: &[&WriteRequest]) -> Option<Fault> {
        let mut state = self.state.lock().expect("faults lock");
        state.transactions += 1;
        let k = state.transactions;
        // An append holds the samples from its seq on (batches gathered into one request
        // make one append that starts at the first of them).
        let holds = |stroke: &Uuid, seq: &u64| {
            requests.iter().flat_map(|r| &r.ops).any(|op| {
                matches!(op, WriteOp::Append { stroke: s, seq: q, samples }
                    if s == stroke && (*q..*q + samples.len() as u64).contains(seq))
            })
        };
        let begins = |stroke: &Uuid| {
            requests
                .iter()
                .flat_map(|r| &r.ops)
                .any(|op| matches!(op, WriteOp::BeginStroke { stroke: s, .. } if s == stroke))
        };
        let removes = |stroke: &Uuid| {
            requests
                .iter()
                .flat_map(|r| &r.ops)
                .any(|op| matches!(op, WriteOp::SetRemoved { stroke: s, .. } if s == stroke))
        };
        let rule = state.rules.iter_mut().find(|r| {
            r.remaining > 0
                && match &r.target {
                    FaultTarget::Transaction(n) => *n == k,
                    FaultTarget::Append { stroke, seq } => holds(stroke, seq),
                    FaultTarget::Begin { stroke } => begins(stroke),
                    FaultTarget::Removal { stroke } => removes(stroke),
                }
        })?;
        rule.remaining -= 1;
        Some(rule.fault)
    }
}
