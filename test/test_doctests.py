"""
The examples in the docstrings of the correlations, the oil and the Mellor blocks run.

Each physics function carries an example with a published or hand-checked
value (as CalebBell's ``ht`` does); here they run as doctests, so a docstring
cannot drift from the code. numba's compiled functions are found through
their ``py_func`` as well, whatever numba version hides or shows their
docstrings to :mod:`doctest`.
"""

import doctest
import inspect
import io

import pytest
from wet_eha_thermal.model import (correlations, fluid_power, hot_spot, losses, mellor, oil,
                                   rotor_losses, stator_harmonics, winding)

MODULES = (correlations, oil, mellor, losses, rotor_losses, stator_harmonics, fluid_power,
           hot_spot, winding)

#: Public functions and methods of MODULES without an example of their own, and why.
NO_EXAMPLE = {
    'correlations.airgap_friction_kernel': 'compiled kernel of airgap_friction (its examples)',
    'correlations.laminar_turbulent_nusselt': 'the law behind annulus_axial_nusselt and '
                                              'pipe_internal_nusselt (their examples)',
    'correlations.laminar_turbulent_nusselt_kernel': 'compiled laminar_turbulent_nusselt',
    'correlations.bilgen_boulos_regime_kernel': 'regime of bilgen_boulos_torque_coefficient',
    'correlations.airgap_friction_factors': "airgap_friction's geometry constants (its examples)",
    'correlations.check_airgap_friction': 'flags the validity of airgap_friction; no value',
    'correlations.daily_nece_moment_coefficient_kernel': 'compiled regime choice of '
                                                         'daily_nece_moment_coefficient',
    'correlations.daily_nece_laws': "daily_nece_moment_coefficient's constants at one G",
    'correlations.check_enclosed_disc_nusselt': 'flags the validity of enclosed_disc_nusselt',
    'correlations.enclosed_disc_nusselt_kernel': 'compiled kernel of enclosed_disc_nusselt',
    'correlations.check_flat_plate_nusselt': 'flags the validity of flat_plate_nusselt',
    'correlations.flat_plate_nusselt_kernel': 'compiled kernel of flat_plate_nusselt',
    'correlations.enclosed_disc_friction': 'compiled power of daily_nece_moment_coefficient '
                                           '(its examples; test_end_spaces.py)',
    'oil.density': 'the law of Oil.density without checks (its example)',
    'oil.kinematic_viscosity': 'the law of Oil.kinematic_viscosity without checks',
    'oil.specific_heat': 'the law of Oil.specific_heat without checks',
    'oil.conductivity': 'the law of Oil.conductivity without checks',
    'oil.get_oil': 'looks a grade up by name (every oil example calls it)',
    'oil.OilGrade.walther_hot': "walther_fit of the grade's data (Oil.kinematic_viscosity)",
    'oil.OilGrade.walther_cold': "walther_fit of the grade's data (Oil.kinematic_viscosity)",
    'oil.Oil.name': 'a datum of the grade',
    'oil.Oil.alpha_p': 'a datum of the grade',
    'oil.secant_bulk_modulus': 'the law of Oil.secant_bulk_modulus without checks',
    'fluid_power.displacement_per_rad': 'a unit conversion',
    'fluid_power.check_gap_leakage': 'flags the validity of gap_leakage; no value',
    'fluid_power.check_line_pressure_drop': 'flags the validity of line_pressure_drop; no value',
    'fluid_power.pump_friction_torque': 'the lumped friction law of docs/model.md (test_kinetics)',
    'fluid_power.line_pressure_drop': 'Darcy with 64/Re and Blasius (test_kinetics, test_eha)',
    'fluid_power.line_pressure_drop_kernel': 'compiled kernel of line_pressure_drop',
    'mellor.add_cylinder': 'wires mellor_resistances into a network (test_mellor.py)',
    'mellor.Cylinder.slices': 'counts node names',
    'rotor_losses.harmonic_losses': 'checked against FE and Bessel solutions (test_rotor_losses)',
    'rotor_losses.magnet_fundamental_field_T': 'through implied_turns_per_phase (its test)',
    'rotor_losses.fundamental_sheet_per_amp': 'through implied_turns_per_phase (its test)',
    'rotor_losses.implied_turns_per_phase': 'test_rotor_losses: about 36 turns on the rig',
    'stator_harmonics.pwm_current_harmonics': 'pwm_ripple_current_rms_A sums it (its example)',
    'stator_harmonics.pwm_ripple_ac_factor': 'copper_ac_factor over pwm_current_harmonics',
    'hot_spot.slot_peak_forms': 'slot_section_field at the network (test_fem_check: the FE peak)',
    'hot_spot.end_winding_peak_forms': 'cylinder_profile and slab_profile of an end winding',
    'winding.check_winding': 'raises on contradictions (test_winding: each message)',
    'rotor_losses.rotor_eddy_loss_breakdown': 'harmonic_losses per wave (test_rotor_losses)',
    'rotor_losses.rotor_eddy_loss_table': 'the breakdown tabulated (test_rotor_losses)',
    'rotor_losses.RotorGeometry.radii': 'a datum of the geometry',
    'rotor_losses.RotorGeometry.mu_r': 'a datum of the geometry',
    'rotor_losses.RotorGeometry.piece_angle_rad': 'a datum of the geometry',
    'rotor_losses.RotorGeometry.piece_width_m': 'a datum of the geometry',
}

# Fewer would mean the collection below lost docstrings (31 docstrings and 59 examples
# when this was written).
MIN_DOCSTRINGS = 31
MIN_EXAMPLES = 59


def prefix(module) -> str:
    """Return the last part of a module's name, the prefix of the short names here."""
    return module.__name__.rsplit('.', 1)[-1]


def collect_doctests() -> dict:
    """Return the doctests with examples of MODULES, by short name (``oil.Oil.density``)."""
    finder = doctest.DocTestFinder()
    tests = {}
    for module in MODULES:
        # numba's dispatchers first, through the Python function they compile: doctest
        # sees a dispatcher's docstring only while numba copies it and the dispatcher
        # passes for a routine
        for name, obj in vars(module).items():
            func = getattr(obj, 'py_func', None)
            if func is not None and func.__module__ == module.__name__:
                for test in finder.find(func, f'{module.__name__}.{name}', module=module,
                                        globs=vars(module)):
                    tests[f'{prefix(module)}.{name}'] = test
        for test in finder.find(module):
            tests.setdefault(prefix(module) + test.name[len(module.__name__):], test)
    return {name: test for name, test in tests.items() if test.examples}


def public_functions() -> set:
    """Return the short names of the public functions, methods and properties of MODULES."""
    names = set()
    for module in MODULES:
        for name, obj in vars(module).items():
            if name.startswith('_') or getattr(obj, '__module__', None) != module.__name__:
                continue
            if inspect.isclass(obj):
                names.update(f'{prefix(module)}.{name}.{attr}'
                             for attr, member in vars(obj).items() if not attr.startswith('_')
                             and (inspect.isfunction(member) or isinstance(member, property)))
            elif callable(obj):
                names.add(f'{prefix(module)}.{name}')
    return names


DOCTESTS = collect_doctests()


@pytest.mark.parametrize('name', sorted(DOCTESTS))
def test_docstring_examples_run(name):
    runner = doctest.DocTestRunner()
    out = io.StringIO()
    result = runner.run(DOCTESTS[name], out=out.write)
    assert result.failed == 0, out.getvalue()


def test_the_examples_are_all_collected():
    examples = sum(len(test.examples) for test in DOCTESTS.values())
    assert len(DOCTESTS) >= MIN_DOCSTRINGS and examples >= MIN_EXAMPLES, \
        f'only {len(DOCTESTS)} docstrings with {examples} examples collected'


def test_every_physics_function_has_an_example():
    public = public_functions()
    assert set(NO_EXAMPLE) <= public, 'NO_EXAMPLE names what is gone'
    assert not set(NO_EXAMPLE) & set(DOCTESTS), 'NO_EXAMPLE names what has an example'
    missing = public - set(DOCTESTS) - set(NO_EXAMPLE)
    assert not missing, f'public functions without an example: {sorted(missing)}'
