"""The audit log of privileged actions (issue #25): :class:`.log.AuditLog`.

Owns the ``audit_log`` rows: who acted, what they did, on what, when, from
which address. Routes write a row after a privileged action succeeds;
administrators read them (``GET /api/audit``, ``/api/audit.csv``).
**Invariant: rows are only added, never changed; no password or token is
ever in a row; the audit log imports no other domain folder.**
"""
