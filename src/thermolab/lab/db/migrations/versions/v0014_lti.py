"""The LTI 1.3 tool: platforms, keys, login states, identities, contexts, links, grades.

Revision ID: 0014
Revises: 0009
Create Date: 2026-11-24

See :mod:`thermolab.lab.db.lti_models` for what each table holds.
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision: str = "0014"
down_revision: str | None = "0013"
branch_labels: str | None = None
depends_on: str | None = None

_URL = 1024


def _fk(table: str, column: str, target: str) -> sa.ForeignKeyConstraint:
    return sa.ForeignKeyConstraint(
        [column],
        [f"{target}.id"],
        name=op.f(f"fk_{table}_{column}_{target}"),
        ondelete="CASCADE",
    )


def upgrade() -> None:
    op.create_table(
        "lti_platforms",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("issuer", sa.String(255), nullable=False),
        sa.Column("client_id", sa.String(255), nullable=False),
        sa.Column("auth_login_url", sa.String(_URL), nullable=False),
        sa.Column("token_url", sa.String(_URL), nullable=False),
        sa.Column("jwks_url", sa.String(_URL), nullable=False),
        sa.Column("deployment_ids", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_platforms")),
        sa.UniqueConstraint("issuer", "client_id", name=op.f("uq_lti_platforms_issuer_client_id")),
    )
    op.create_table(
        "lti_keys",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("kid", sa.String(64), nullable=False),
        sa.Column("private_pem", sa.Text(), nullable=False),
        sa.Column("public_jwk", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("retired_at", sa.DateTime(timezone=True), nullable=True),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_keys")),
        sa.UniqueConstraint("kid", name=op.f("uq_lti_keys_kid")),
    )
    op.create_table(
        "lti_login_states",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("state_hash", sa.String(64), nullable=False),
        sa.Column("nonce", sa.String(64), nullable=False),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("expires_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("used_at", sa.DateTime(timezone=True), nullable=True),
        _fk("lti_login_states", "platform_id", "lti_platforms"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_login_states")),
        sa.UniqueConstraint("state_hash", name=op.f("uq_lti_login_states_state_hash")),
        sa.UniqueConstraint("nonce", name=op.f("uq_lti_login_states_nonce")),
    )
    op.create_index(op.f("ix_lti_login_states_platform_id"), "lti_login_states", ["platform_id"])
    op.create_table(
        "lti_identities",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("sub", sa.String(255), nullable=False),
        sa.Column("user_id", sa.Integer(), nullable=False),
        _fk("lti_identities", "platform_id", "lti_platforms"),
        _fk("lti_identities", "user_id", "users"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_identities")),
        sa.UniqueConstraint("platform_id", "sub", name=op.f("uq_lti_identities_platform_id_sub")),
    )
    op.create_index(op.f("ix_lti_identities_platform_id"), "lti_identities", ["platform_id"])
    op.create_index(op.f("ix_lti_identities_user_id"), "lti_identities", ["user_id"])
    op.create_table(
        "lti_contexts",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("context_id", sa.String(255), nullable=False),
        sa.Column("course_id", sa.Integer(), nullable=False),
        sa.Column("memberships_url", sa.String(_URL), nullable=True),
        sa.Column("lineitems_url", sa.String(_URL), nullable=True),
        _fk("lti_contexts", "platform_id", "lti_platforms"),
        _fk("lti_contexts", "course_id", "courses"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_contexts")),
        sa.UniqueConstraint(
            "platform_id", "context_id", name=op.f("uq_lti_contexts_platform_id_context_id")
        ),
    )
    op.create_index(op.f("ix_lti_contexts_platform_id"), "lti_contexts", ["platform_id"])
    op.create_index(op.f("ix_lti_contexts_course_id"), "lti_contexts", ["course_id"])
    op.create_table(
        "lti_resource_links",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("link_id", sa.String(255), nullable=False),
        sa.Column("target", sa.String(255), nullable=True),
        sa.Column("lineitem_url", sa.String(_URL), nullable=True),
        _fk("lti_resource_links", "platform_id", "lti_platforms"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_resource_links")),
        sa.UniqueConstraint(
            "platform_id", "link_id", name=op.f("uq_lti_resource_links_platform_id_link_id")
        ),
    )
    op.create_index(
        op.f("ix_lti_resource_links_platform_id"), "lti_resource_links", ["platform_id"]
    )
    op.create_index(op.f("ix_lti_resource_links_target"), "lti_resource_links", ["target"])
    op.create_table(
        "lti_grades",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("platform_id", sa.Integer(), nullable=False),
        sa.Column("lineitem_url", sa.String(_URL), nullable=False),
        sa.Column("sub", sa.String(255), nullable=False),
        sa.Column("score_given", sa.Float(), nullable=False),
        sa.Column("score_maximum", sa.Float(), nullable=False),
        sa.Column("comment", sa.Text(), nullable=True),
        sa.Column("timestamp", sa.DateTime(timezone=True), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("attempts", sa.Integer(), nullable=False),
        sa.Column("next_attempt_at", sa.DateTime(timezone=True), nullable=False),
        sa.Column("last_error", sa.Text(), nullable=True),
        sa.Column("sent_at", sa.DateTime(timezone=True), nullable=True),
        sa.CheckConstraint(
            "status IN ('pending', 'sent', 'failed')", name=op.f("ck_lti_grades_status")
        ),
        _fk("lti_grades", "platform_id", "lti_platforms"),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_lti_grades")),
    )
    op.create_index(op.f("ix_lti_grades_platform_id"), "lti_grades", ["platform_id"])
    op.create_index(op.f("ix_lti_grades_status"), "lti_grades", ["status"])


def downgrade() -> None:
    for table in (
        "lti_grades",
        "lti_resource_links",
        "lti_contexts",
        "lti_identities",
        "lti_login_states",
        "lti_keys",
        "lti_platforms",
    ):
        op.drop_table(table)
