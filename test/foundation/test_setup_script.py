"""run.sh and env.sh: idempotent setup and loud, named failures."""

import os
import pathlib
import shutil
import subprocess

REPOSITORY = pathlib.Path(__file__).resolve().parents[2]


def test_second_setup_does_nothing():
    result = subprocess.run([str(REPOSITORY / 'run.sh'), 'setup'], capture_output=True,
                            text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout == '' and result.stderr == '', 'setup redid work with nothing changed'


def test_unknown_job_is_a_usage_error():
    result = subprocess.run([str(REPOSITORY / 'run.sh'), 'fly'], capture_output=True, text=True)
    assert result.returncode == 2
    assert 'usage' in result.stderr and 'demo|test|setup' in result.stderr


def test_env_sh_before_setup_says_to_run_setup(tmp_path):
    shutil.copy(REPOSITORY / 'env.sh', tmp_path / 'env.sh')
    result = subprocess.run(['bash', '-c', f'source "{tmp_path}/env.sh"; echo "status=$?"'],
                            capture_output=True, text=True)
    assert 'status=1' in result.stdout
    assert 'run.sh setup' in result.stderr and 'not set up' in result.stderr


def test_setup_without_a_suitable_python_names_it(tmp_path):
    # A PATH whose only python3 is too old (it fails the version check) and no python3.1x.
    tools = tmp_path / 'bin'
    tools.mkdir()
    for tool in ('bash', 'dirname', 'cat', 'rm', 'find', 'sort', 'xargs', 'sha256sum', 'cut'):
        os.symlink(shutil.which(tool), tools / tool)
    old_python = tools / 'python3'
    old_python.write_text('#!/bin/sh\necho "Python 3.8.10"\nexit 1\n')
    old_python.chmod(0o755)
    workspace = tmp_path / 'repo'
    workspace.mkdir()
    shutil.copy(REPOSITORY / 'run.sh', workspace / 'run.sh')
    result = subprocess.run([str(tools / 'bash'), str(workspace / 'run.sh'), 'setup'],
                            env={'PATH': str(tools)}, capture_output=True, text=True)
    assert result.returncode != 0
    assert 'no Python >= 3.10 found' in result.stderr
    assert not (workspace / '.venv').exists(), 'a failed setup left a half-made venv'
