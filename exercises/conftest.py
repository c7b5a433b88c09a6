"""Local runs (``pytest NN_topic`` from this folder): the ``student`` fixture is your module.

Each test file names the module it tests in ``MODULE``; the fixture imports that file
from the test's folder, fresh for every test. (While grading, the grader supplies its
own ``student`` fixture and ignores this file.)
"""

import importlib.util
from pathlib import Path

import pytest


@pytest.fixture
def student(request):
    name = request.module.MODULE
    path = Path(request.module.__file__).with_name(f"{name}.py")
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
