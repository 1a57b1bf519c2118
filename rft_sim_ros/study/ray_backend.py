"""Run a study's items as Ray tasks on a Ray cluster (optional: `pip install
rft_sim_ros[ray]`), with the same Outcome stream as the local pool.

address: what `ray.init` takes: 'auto' (the cluster this machine belongs to, as `ray start`
left it or RAY_ADDRESS says), 'HOST:PORT' of a head node, 'ray://HOST:10001' (Ray Client),
or 'local' (start a throwaway single-machine cluster for this study, dashboard off).
Each item is one task (one CPU); Ray retries a task once when its worker process dies; results
stream back as tasks finish. Ray reuses worker processes, so `execute`'s once-per-process
warm-up holds there too. Every node needs rft_sim_ros (same version) and any scene file the
study names at the same path.
"""
from .pool import Outcome
from .spec import StudyError

#: Retries of a task whose worker process died (as the local pool: one).
RETRIES = 1


def connect(address):
    """Connect to (or, for 'local', start) a Ray cluster; returns True if this call started
    Ray in this process (and so should shut it down). Raises StudyError without Ray or when
    no cluster answers at `address`."""
    try:
        import ray
    except ImportError:
        raise StudyError('--ray needs Ray: pip install "rft_sim_ros[ray]"') from None
    if ray.is_initialized():
        return False
    options = {'include_dashboard': False} if address == 'local' else {}
    try:
        ray.init(address=address, logging_level='WARNING', log_to_driver=False, **options)
    except (ConnectionError, ValueError, RuntimeError) as error:
        raise StudyError(f'--ray {address}: no Ray cluster to connect to '
                         f'({str(error).splitlines()[0]}); start one with `ray start --head` '
                         "or use --ray local") from None
    return True


def map_unordered(fn, items, address='auto'):
    """Yield an Outcome per item as each Ray task finishes (fn: a module-level function,
    pickled by reference, so rft_sim_ros must be importable on every node)."""
    import ray
    from ray.exceptions import RayError

    started_here = connect(address)
    pending = {}
    try:
        remote = ray.remote(num_cpus=1, max_retries=RETRIES, retry_exceptions=False)(fn)
        pending = {remote.remote(item): index for index, item in enumerate(items)}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                index = pending.pop(ref)
                try:
                    yield Outcome(index, ray.get(ref))
                except RayError as error:  # the worker died twice, or fn raised
                    yield Outcome(index, error=f'{type(error).__name__}: '
                                               f'{str(error).splitlines()[0]}')
    finally:
        for ref in pending:  # the study was interrupted
            ray.cancel(ref, force=True)
        if started_here:
            ray.shutdown()
