"""The study's tables, registered as a third party registers one (:func:`harness.report.tables.register_table`;
this module is named by the project's ``harness.tables`` entry point)."""

from __future__ import annotations

from harness.report.tables import register_table
from harness.study.claims import table_claims

register_table("claims", build=table_claims,
               title="The paper's claims, each tested as the paper states it, with a verdict")
