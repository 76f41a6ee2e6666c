# The two README commands: `make study` and `make test`. Both create .venv when absent.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
LAB_STAMP := $(VENV)/.lab-installed

.PHONY: study study-check study-nordland test install lab git-filter bench lint clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name python3 --display-name "Python 3 (vpr-landmarks)" >/dev/null
	touch $(STAMP)

install: $(STAMP) git-filter

$(LAB_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install -q -e '.[dev,lab]'
	touch $(LAB_STAMP)

# The git filter of this clone (.git/config; .gitattributes names the notebooks): the outputs,
# execution counts, run metadata and Lab's view state that JupyterLab saves into a study
# notebook (the catalogue's, by path: vpr_study/nbclean.py) never reach git; cell ids are kept,
# and any other notebook is the user's and passes unchanged (the same rule as `make lab`'s save
# hook). The commands are relative (git runs them at the top of the work tree), so they work in
# any clone, moved or not, and need only the system Python (no .venv: a fresh clone and
# `make clean` strip the same). `make install` and `make lab` run it. The filter is `required`
# and fails closed: a study notebook it cannot strip stops the `git add` with a sentence, so its
# outputs never reach git through an error. Outside a git clone it does nothing.
STRIP := sh tools/nbstrip
git-filter:
	@if git rev-parse --git-dir >/dev/null 2>&1; then \
		git config --local filter.nbstripout.clean '$(STRIP) --clean %f' && \
		git config --local filter.nbstripout.smudge cat && \
		git config --local filter.nbstripout.required true && \
		git config --local diff.ipynb.textconv '$(STRIP)'; fi

study: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/vpr-study run --dataset synthetic
	MPLBACKEND=Agg $(VENV)/bin/vpr-study eval --study --dataset synthetic --method dense classical

# `make study`, then fail when a committed figure or table is not byte-identical to the one just
# regenerated (or a new one appeared): the outputs-identical check of issue 35. Too slow for the
# CI budget from an empty cache; run it before committing outputs.
study-check: study
	@out="$$(git status --porcelain -- figures results)"; if [ -n "$$out" ]; then \
		echo "$$out"; echo "study-check: regenerated outputs differ from the committed ones" \
		"(on another CPU family than the one that made them, a sixth decimal and a few PNGs" \
		"can differ: docs/MEASUREMENTS.md, Across CPU families; git diff shows which)"; \
		exit 1; fi; echo "study-check: every committed figure and table is byte-identical"

# Notebooks 05-07 on 716 Nordland places (every 5th of nordland_64x32, winter vs summer), roi
# pooling, each query's top 25 references re-ranked by Eq. (1): 16 min 10 s from an empty cache
# on a 2-core machine for 05-06, and about 5 min more for 07 (docs/MEASUREMENTS.md,
# study-nordland). Then the findings table with every result folder.
study-nordland: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/vpr-study run --dataset nordland --root ../shared/data/nordland_64x32 \
		--step 5 --tolerance 0 --pooling roi --shortlist 25 --label nordland_step5 \
		--notebooks 05_dense_sampling_parameters 06_comparison 07_places_alike
	$(VENV)/bin/vpr-study findings --write

test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -q -n 2 --dist loadfile

# JupyterLab on the project, on 127.0.0.1 with its token; --allow-root only when run as root
# (containers, cloud machines). It opens the starter notebook in user/notebooks/ (git-ignored,
# a user's own; copied there when absent, never replaced) beside the study's notebooks/; a
# user's own cells save under user/. The save hook strips only the committed study notebooks;
# the contents manager (vpr_study.lab.StudyContentsManager, jupytext's) serves them with the
# kernel's language_info, so opening one leaves it unmodified, and puts a Duplicate of one in
# user/notebooks/.
# Kernels share the project's .cache/ whatever their working directory. The [lab] extra
# (jupyterlab, ipywidgets) is installed once ($(LAB_STAMP)), again only when pyproject.toml changes.
lab: $(LAB_STAMP) git-filter
	$(PY) -m vpr_study.lab init
	$(VENV)/bin/jupyter lab --ip=127.0.0.1 --ServerApp.root_dir="$(CURDIR)" \
		--ServerApp.contents_manager_class=vpr_study.lab.StudyContentsManager \
		--ContentsManager.pre_save_hook=vpr_study.lab.strip_outputs \
		--LabApp.default_url=/lab/tree/user/notebooks/00_start_here.ipynb \
		$(if $(filter 0,$(shell id -u)),--allow-root)

bench: $(STAMP)
	for f in benchmarks/bench_*.py; do $(PY) $$f || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check vpr_core vpr_study tests benchmarks
	$(VENV)/bin/ruff format --check vpr_core vpr_study tests benchmarks
	$(VENV)/bin/mypy

# The install (.venv, PyTorch with it), every cached dataset, landmark, feature and matrix
# (.cache) and the executed notebooks (runs/); figures/, results/ and user/ stay (README).
# JupyterLab and its kernels run from .venv: while a process of this checkout runs from it
# (make lab, a kernel, a test worker), nothing is removed and the message says to stop it.
clean:
	@if pgrep -f "$(CURDIR)/[.]venv/bin/" >/dev/null 2>&1; then \
		echo "make clean: a process runs from this checkout's .venv (JupyterLab, a kernel," \
			"tests): stop it first (Ctrl-C in the terminal of make lab), then run make clean" \
			"again; nothing was removed"; exit 1; fi
	rm -rf $(VENV) .cache runs
	@echo "make clean: removed .venv (the install, PyTorch with it: the next make reinstalls" \
		"it), .cache/ (generated datasets, landmarks, features, matrices) and runs/ (executed" \
		"notebooks); kept: user/ (your notebooks, figures and tables), figures/ and results/" \
		"(the study's, committed)"
