"""The host memory available to a new allocation: what the replay buffers check before they allocate."""

try:
    import psutil
except ImportError:  # pragma: no cover
    psutil = None


def available_host_memory() -> int | None:
    """
    :return: the host memory available to a new allocation, in bytes: psutil's (as SB3 reads it) or, without psutil
        (not a dependency), Linux's ``MemAvailable``; None where neither can be read
    """
    if psutil is not None:
        return int(psutil.virtual_memory().available)
    try:
        with open("/proc/meminfo") as file:
            for line in file:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None
