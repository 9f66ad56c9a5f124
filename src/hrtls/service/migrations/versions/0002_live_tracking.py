"""Live tracking: mission path-loss channel, agent mounting, snapshot t_final.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = '0002'
down_revision = '0001'
branch_labels = None
depends_on = None


def upgrade() -> None:
    """Apply."""
    with op.batch_alter_table('agents', schema=None) as batch_op:
        batch_op.add_column(sa.Column('mounting_q_bd', sa.JSON(), nullable=True))

    with op.batch_alter_table('missions', schema=None) as batch_op:
        batch_op.add_column(sa.Column('channel', sa.JSON(), nullable=True))

    # snapshots are a cache of the raw log: older ones without t_final are dropped
    op.execute("DELETE FROM tracker_snapshots")
    with op.batch_alter_table('tracker_snapshots', schema=None) as batch_op:
        batch_op.add_column(sa.Column('t_final', sa.Float(), nullable=False))


def downgrade() -> None:
    """Revert."""
    with op.batch_alter_table('tracker_snapshots', schema=None) as batch_op:
        batch_op.drop_column('t_final')

    with op.batch_alter_table('missions', schema=None) as batch_op:
        batch_op.drop_column('channel')

    with op.batch_alter_table('agents', schema=None) as batch_op:
        batch_op.drop_column('mounting_q_bd')
