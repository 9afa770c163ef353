# hyperfem: `make demo` and `make test` bootstrap .venv on first use.
#
# Bootstrap: if a Python with DOLFINx >= 0.10 is importable (Debian's
# python3-dolfinx, conda), the venv is made with --system-site-packages and
# only what that Python lacks (gmsh, meshio, pytest, matplotlib) is added; its
# ufl/ffcx/basix/petsc4py are never shadowed. Otherwise a Python >= 3.12 gets
# the PyPI wheel dolfinx-solver-real. Re-running is a no-op when nothing changed.

SHELL := /bin/bash
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.hyperfem-bootstrap
NP ?= 2
PYTEST_ARGS ?= -q -p no:cacheprovider

# Debian's MUMPS uses threaded OpenBLAS: one thread per rank unless the user chose.
export OMP_NUM_THREADS ?= 1
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: all bootstrap demo demos test test-serial test-mpi lint meshes benchmark render clean

all: test

bootstrap: $(STAMP)

$(STAMP): pyproject.toml Makefile
	@set -e; \
	has_dolfinx='from mpi4py import MPI; import dolfinx, sys; v = tuple(int(x) for x in dolfinx.__version__.split(".")[:2]); sys.exit(0 if v >= (0, 10) else 1)'; \
	is_312='import sys; sys.exit(0 if sys.version_info >= (3, 12) else 1)'; \
	sys_py=""; \
	for c in python3 /usr/bin/python3 /usr/local/bin/python3 "$${CONDA_PREFIX:+$$CONDA_PREFIX/bin/python}"; do \
	  [ -n "$$c" ] || continue; \
	  if command -v "$$c" >/dev/null 2>&1 && "$$c" -c "$$has_dolfinx" >/dev/null 2>&1; then sys_py="$$c"; break; fi; \
	done; \
	if [ ! -x "$(PY)" ]; then \
	  if [ -n "$$sys_py" ]; then \
	    echo "bootstrap: using the system DOLFINx of $$sys_py (--system-site-packages)"; \
	    "$$sys_py" -m venv --system-site-packages "$(VENV)"; \
	  else \
	    py=""; \
	    for c in python3.13 python3.12 python3 $$(ls -d $${PYENV_ROOT:-$$HOME/.pyenv}/versions/3.1[2-9]*/bin/python3 2>/dev/null); do \
	      if command -v "$$c" >/dev/null 2>&1 && "$$c" -c "$$is_312" >/dev/null 2>&1; then py="$$c"; break; fi; \
	    done; \
	    if [ -z "$$py" ]; then \
	      echo "bootstrap: error: need a Python >= 3.12 (for the dolfinx-solver-real wheel) or a Python with DOLFINx >= 0.10; found neither" >&2; \
	      exit 1; \
	    fi; \
	    echo "bootstrap: no system DOLFINx >= 0.10; using $$py and the PyPI wheel dolfinx-solver-real"; \
	    "$$py" -m venv "$(VENV)"; \
	  fi; \
	fi; \
	"$(PY)" -m pip install -q --upgrade pip >/dev/null; \
	if "$(PY)" -c "$$has_dolfinx" >/dev/null 2>&1 && ! "$(PY)" -c 'import sys, dolfinx; sys.exit(0 if dolfinx.__file__.startswith(sys.prefix) else 1)' 2>/dev/null; then \
	  extras=""; \
	  for m in gmsh meshio pytest matplotlib jsonschema; do "$(PY)" -c "import $$m" >/dev/null 2>&1 || extras="$$extras $$m"; done; \
	  [ -z "$$extras" ] || "$(PY)" -m pip install -q $$extras; \
	  "$(PY)" -m pip install -q "mypy>=2.4,<2.5" "ruff>=0.17,<0.18"; \
	  "$(PY)" -m pip install -q --no-deps -e . >"$(VENV)/bootstrap.log" 2>&1 || { cat "$(VENV)/bootstrap.log"; exit 1; }; \
	else \
	  "$(PY)" -m pip install -q -e ".[wheel,mesh,test,plot,lint]" >"$(VENV)/bootstrap.log" 2>&1 || { cat "$(VENV)/bootstrap.log"; exit 1; }; \
	fi; \
	"$(PY)" -c "import ipctk" >/dev/null 2>&1 || "$(PY)" -m pip install -q "ipctk>=1.6,<1.7" >/dev/null 2>&1 \
	  || echo "bootstrap: ipctk not available: contact tests skip"; \
	"$(PY)" -c "$$has_dolfinx" || { echo "bootstrap: error: DOLFINx >= 0.10 not importable in $(VENV)" >&2; exit 1; }; \
	touch "$(STAMP)"; \
	echo "bootstrap: $(VENV) ready ($$("$(PY)" -c 'from mpi4py import MPI; import dolfinx; print("DOLFINx", dolfinx.__version__)'))"

# mpiexec matching the MPI that mpi4py was built against (the wheel ships MPICH).
MPIEXEC = $(shell [ -x $(VENV)/bin/mpiexec ] && echo $(VENV)/bin/mpiexec || echo mpiexec)

demo: bootstrap
	$(PY) demos/bend.py

demos: bootstrap
	$(PY) demos/bend.py
	$(PY) demos/twist.py
	$(PY) demos/muscle.py
	$(PY) demos/dynamics.py --case bend --t-end 0.5
	$(PY) demos/muscle_dynamics.py
	$(PY) demos/methods.py --case bend --t-end 0.1
	$(PY) demos/realtime.py --steps 90
	$(PY) demos/contact.py
	$(PY) demos/surgery.py
	$(PY) demos/two_beams.py
	$(PY) demos/glued_bar.py
	$(PY) demos/fold.py
	$(PY) demos/fit_treloar.py
	$(PY) demos/relaxation.py
	$(PY) demos/inflation.py
	$(PY) demos/buckling.py

test: bootstrap
	$(PY) -m pytest $(PYTEST_ARGS)
	$(MPIEXEC) -n $(NP) $(PY) -m pytest $(PYTEST_ARGS)

# ruff (style, bugs) and mypy (the library's types, [tool.mypy] in pyproject.toml); CI runs it after the tests.
lint: bootstrap
	$(PY) -m ruff check hyperfem tests demos benchmarks docs
	$(PY) -m mypy

test-serial: bootstrap
	$(PY) -m pytest $(PYTEST_ARGS)

test-mpi: bootstrap
	$(MPIEXEC) -n $(NP) $(PY) -m pytest $(PYTEST_ARGS)

meshes: bootstrap
	$(PY) -c "from hyperfem.mesh import write_beam_mesh as w; w('meshes/beam_h2.msh', h=2.0); w('meshes/beam_h1.msh', h=1.0)"

# Optional: pyvista (offscreen VTK) for the PNG renders, and the README pictures redrawn.
render: bootstrap
	$(PY) -c "import pyvista" 2>/dev/null || $(PY) -m pip install -q pyvista
	$(PY) docs/render_images.py

benchmark: bootstrap
	$(PY) benchmarks/energy_line_search.py
	$(PY) benchmarks/dynamics_frequency.py

clean:
	rm -rf output .pytest_cache
