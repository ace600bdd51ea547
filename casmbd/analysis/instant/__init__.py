"""One instant of a mechanism: assembly, accelerations and multipliers (KKT), redundancy,
independent equations, culprits of a failed assembly, first-evaluation checks, reactions and
joint friction."""
