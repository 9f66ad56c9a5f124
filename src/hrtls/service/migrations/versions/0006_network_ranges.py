"""Ranges between the dropped nodes: their log, and how far a mission snapshot read it.

Revision ID: 0006
Revises: 0005
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0006'
down_revision = '0005'
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Apply."""
    op.create_table(
        'network_range_batches',
        sa.Column('id', sa.Integer(), nullable=False),
        sa.Column('mission_id', sa.Integer(), nullable=False),
        sa.Column('seq', sa.Integer(), nullable=False),
        sa.Column('received_unix', sa.Float(), nullable=False),
        sa.Column('t_first', sa.Float(), nullable=False),
        sa.Column('t_last', sa.Float(), nullable=False),
        sa.Column('rows', sa.Integer(), nullable=False),
        sa.Column('body', sa.LargeBinary(), nullable=False),
        sa.ForeignKeyConstraint(['mission_id'], ['missions.id'], ondelete='CASCADE'),
        sa.PrimaryKeyConstraint('id'),
        sa.UniqueConstraint('mission_id', 'seq', name='uq_network_range_seq'))
    with op.batch_alter_table('mission_snapshots') as batch:
        batch.add_column(sa.Column('net_raw_id', sa.Integer(), nullable=False,
                                   server_default='0'))


def downgrade() -> None:
    """Revert."""
    with op.batch_alter_table('mission_snapshots') as batch:
        batch.drop_column('net_raw_id')
    op.drop_table('network_range_batches')
