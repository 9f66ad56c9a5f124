"""Landmark versions: every written version of a landmark with the mission time it holds from.

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0004'
down_revision = '0003'
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Apply; the landmarks stored so far become versions of their mission's start."""
    op.create_table(
        'landmark_versions',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('mission_id', sa.Integer(), nullable=False),
        sa.Column('key', sa.String(length=200), nullable=False),
        sa.Column('t', sa.Float(), nullable=True),
        sa.Column('data', sa.JSON(), nullable=False),
        sa.ForeignKeyConstraint(['mission_id'], ['missions.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'))
    op.create_index('ix_landmark_version_mission', 'landmark_versions', ['mission_id', 't'])
    op.execute("INSERT INTO landmark_versions (mission_id, key, t, data) "
               "SELECT mission_id, key, NULL, data FROM landmarks")


def downgrade() -> None:
    """Revert."""
    op.drop_index('ix_landmark_version_mission', table_name='landmark_versions')
    op.drop_table('landmark_versions')
