"""FCLIB files written by libhdf5 through h5py, for tests/fuzz_fclib.rs: here, files with objects
that hdf5-pure does not write (links, external raw data, a dataset declared and never written),
each a typed error; in tests/fuzz_corpus/fclib/, valid files in forms of libhdf5 that gelenk's
writer does not use (the newest format's groups, compact datasets, dense link storage), starting
points of the byte-level target. Run: python3 tests/data/fclib/make_libhdf5_cases.py (needs
h5py, numpy)."""
import os
import h5py
import numpy as np

here = os.path.dirname(os.path.abspath(__file__))
source = os.path.join(here, "..", "..", "problems", "formats", "stack2-cone-0000.hdf5")


corpus = os.path.join(here, "..", "..", "fuzz_corpus", "fclib")


def copy(name, folder=here, layout=None, **kwargs):
    """The committed stack2 problem as a new file `name` (a libhdf5 copy of every dataset)."""
    out = h5py.File(os.path.join(folder, name), "w", **kwargs)
    with h5py.File(source, "r") as f:
        for group in ["fclib_local/W", "fclib_local/vectors"]:
            for key, dataset in f[group].items():
                data = dataset[()]
                if layout is None:
                    out[f"{group}/{key}"] = data
                else:
                    dcpl = h5py.h5p.create(h5py.h5p.DATASET_CREATE)
                    dcpl.set_layout(layout)
                    space = h5py.h5s.create_simple(data.shape)
                    dtype = h5py.h5t.py_create(data.dtype)
                    parent = out.require_group(group)
                    made = h5py.h5d.create(parent.id, key.encode(), dtype, space, dcpl=dcpl)
                    made.write(h5py.h5s.ALL, h5py.h5s.ALL, data)
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

copy("libhdf5-latest-format.hdf5", corpus, libver="latest").close()
copy("libhdf5-compact.hdf5", corpus, layout=h5py.h5d.COMPACT).close()
with copy("libhdf5-dense-links.hdf5", corpus, libver="latest") as f:
    for k in range(24):
        f[f"fclib_local/W/note{k:02d}"] = np.arange(k % 4, dtype="i4")
