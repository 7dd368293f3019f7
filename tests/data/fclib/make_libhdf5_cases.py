"""FCLIB files with objects that hdf5-pure does not write (links, external raw data, a dataset
declared and never written), written by libhdf5 through h5py: regression inputs of
tests/fuzz_fclib.rs. Run: python3 tests/data/fclib/make_libhdf5_cases.py (needs h5py, numpy)."""
import os
import h5py
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
source = os.path.join(here, "..", "..", "problems", "formats", "stack2-cone-0000.hdf5")


def copy(name, **kwargs):
    """The committed stack2 problem as a new file `name` (a libhdf5 copy of every dataset)."""
    out = h5py.File(os.path.join(here, name), "w", **kwargs)
    with h5py.File(source, "r") as f:
        for group in ["fclib_local/W", "fclib_local/vectors"]:
            for key, dataset in f[group].items():
                out[f"{group}/{key}"] = dataset[()]
        out["fclib_local/spacedim"] = f["fclib_local/spacedim"][()]
    return out


for libver, tag in [("earliest", "v1-groups"), ("latest", "v2-groups")]:
    with copy(f"link-soft-mu-{tag}.hdf5", libver=libver) as f:
        f["fclib_local/vectors/mu_data"] = f["fclib_local/vectors/mu"][()]
        del f["fclib_local/vectors/mu"]
        f["fclib_local/vectors/mu"] = h5py.SoftLink("/fclib_local/vectors/mu_data")
    with copy(f"link-soft-vectors-{tag}.hdf5", libver=libver) as f:
        f.move("fclib_local/vectors", "vectors_data")
        f["fclib_local/vectors"] = h5py.SoftLink("/vectors_data")
    with copy(f"link-external-mu-{tag}.hdf5", libver=libver) as f:
        del f["fclib_local/vectors/mu"]
        f["fclib_local/vectors/mu"] = h5py.ExternalLink("/nonexistent/fclib.hdf5", "/fclib_local/vectors/mu")
with copy("external-raw-mu.hdf5") as f:
    del f["fclib_local/vectors/mu"]
    f.create_dataset("fclib_local/vectors/mu", shape=(8,), dtype="f8", external=[("/dev/zero", 0, 64)])
with copy("unwritten-huge-q.hdf5") as f:
    del f["fclib_local/vectors/q"]
    f.create_dataset("fclib_local/vectors/q", shape=(1 << 40,), dtype="f8", chunks=(1024,))
