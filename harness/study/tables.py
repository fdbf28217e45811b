"""The study's tables — ``claims``, ``findings`` generated from it, and the virtual rig against its
goals — registered as a third party registers one (:func:`harness.report.tables.register_table`; this
module is named by the project's ``harness.tables`` entry point). ``claims`` leads the report page
and both colour their verdicts (:mod:`harness.study.claims_lead`)."""

from __future__ import annotations

from harness.report.tables import register_table
from harness.study.claims import table_claims
from harness.study.claims_lead import LEAD, status_of
from harness.study.findings import table_findings
from harness.study.vrgoals import table_virtual_rig

register_table("claims", build=table_claims, verdicts=status_of, lead=LEAD,
               title="The paper's claims, each tested as the paper states it, with a verdict")
register_table("findings", build=table_findings, verdicts=status_of,
               title="Findings: which of the paper's claims hold, fail, depend on the reading or are underpowered")
register_table("virtual_rig", build=table_virtual_rig,
               title="The virtual rig against its goals at 30 % (gap to LightGS and to opacity, met or not)")
