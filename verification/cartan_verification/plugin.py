"""Registers the verification cases through the ``cartan`` entry points (hook
``cartan_register_cases``): ``cartan.registry("cases")`` maps each name to a case instance."""

from __future__ import annotations

from cartan.plugins import hookimpl


def all_cases():
    """One instance of every verification case, in the order of VERIFICATION.md §4."""
    from . import cases_other, cases_rod, cases_static, stiff

    return [
        cases_rod.FreeRigidBody(),
        cases_static.TimoshenkoCantilever(),
        cases_static.EulerBuckling(),
        cases_static.CantileverElastica(),
        cases_rod.AxialWave(),
        cases_rod.AxialWaveFreeEnds(),
        cases_rod.RingFlexuralWave(),
        cases_rod.Butterfly(),
        cases_rod.PlanarEquivalence(),
        cases_other.GreatCircleSlide(),
        cases_other.LatitudeCircle(),
        cases_other.LatitudeCircleSecondOrder(),
        cases_other.SphereRodLargeRadius(),
        cases_other.NullWave(),
        cases_other.HarmonicMapFlowDecay(),
        cases_other.HarmonicMapEnergyBalance(),
        stiff.StiffRodStability(),
    ]


@hookimpl
def cartan_register_cases(register):
    for case in all_cases():
        register(case.name, case)
