"""What is claimed about Cd: the rows on the result's Mach grid (:mod:`~bayesdrag.estimate.cd.table`),
the uncertainty budget by source (:mod:`~bayesdrag.estimate.cd.budget`) and the quality gate that
marks where Cd is determined (:mod:`~bayesdrag.estimate.cd.quality`)."""
