"""Mission networks and the mission estimator's snapshots.

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0005'
down_revision = '0004'
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Apply."""
    op.create_table(
        'mission_networks',
        sa.Column('mission_id', sa.Integer(), nullable=False),
        sa.Column('nodes', sa.JSON(), nullable=False),
        sa.Column('params', sa.JSON(), nullable=False),
        sa.Column('estimates', sa.JSON(), nullable=False),
        sa.Column('horizon_s', sa.Float(), nullable=True),
        sa.ForeignKeyConstraint(['mission_id'], ['missions.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('mission_id'))
    op.create_table(
        'mission_snapshots',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('mission_id', sa.Integer(), nullable=False),
        sa.Column('horizon_s', sa.Float(), nullable=False),
        sa.Column('raw_id', sa.Integer(), nullable=False),
        sa.Column('created_unix', sa.Float(), nullable=False),
        sa.Column('state', sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(['mission_id'], ['missions.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'))
    op.create_index('ix_mission_snapshot_horizon', 'mission_snapshots',
                    ['mission_id', 'horizon_s'])


def downgrade() -> None:
    """Revert."""
    op.drop_index('ix_mission_snapshot_horizon', table_name='mission_snapshots')
    op.drop_table('mission_snapshots')
    op.drop_table('mission_networks')
