// RAII helpers over the HDF5 C API (see include/hinf/h5.hpp). Every failure becomes a hinf::Error
// that names the object; HDF5's own error stack printing is silenced.
#include "hinf/h5.hpp"

#include <filesystem>
#include <type_traits>

#include <cstring>

#include "hinf/error.hpp"

namespace hinf::h5 {

namespace {

struct Silence {
    Silence() { H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr); }
};
const Silence silence_hdf5_errors;

hid_t check(hid_t id, const std::string& what) {
    HINF_CHECK(id >= 0, "HDF5: cannot " + what + " (is the file complete and written by hinf?)");
    return id;
}

void check_status(herr_t st, const std::string& what) {
    HINF_CHECK(st >= 0, "HDF5: cannot " + what + " (disk full, or a damaged file?)");
}

Handle make_dcpl(const std::vector<hsize_t>& dims, bool checksum) {
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
    hsize_t total = 1;
    for (hsize_t d : dims) total *= d;
    if (checksum && total > 0) {
        std::vector<hsize_t> chunk(dims);
        check_status(H5Pset_chunk(dcpl.get(), static_cast<int>(chunk.size()), chunk.data()), "set chunking");
        check_status(H5Pset_fletcher32(dcpl.get()), "enable fletcher32 checksums");
    }
    return dcpl;
}

// Size in bytes of the file that holds loc.
hsize_t file_size(hid_t loc) {
    Handle file(H5Iget_file_id(loc));
    hsize_t size = 0;
    if (file.get() < 0 || H5Fget_filesize(file.get(), &size) < 0) return 0;
    return size;
}

void write_typed(hid_t loc, const std::string& name, hid_t file_type, hid_t mem_type, const void* data,
                 const std::vector<hsize_t>& dims, const std::string& units, const std::string& meaning,
                 bool checksum) {
    Handle space(check(dims.empty() ? H5Screate(H5S_SCALAR)
                                    : H5Screate_simple(static_cast<int>(dims.size()), dims.data(), nullptr),
                       "create dataspace for " + name));
    Handle dcpl = make_dcpl(dims, checksum);
    Handle dset(check(H5Dcreate2(loc, name.c_str(), file_type, space.get(), H5P_DEFAULT, dcpl.get(), H5P_DEFAULT),
                      "create dataset '" + name + "'"));
    check_status(H5Dwrite(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data), "write dataset '" + name + "'");
    if (!units.empty()) set_attr(dset.get(), "units", units);
    if (!meaning.empty()) set_attr(dset.get(), "meaning", meaning);
}

template <typename T>
std::vector<T> read_typed(hid_t loc, const std::string& name, hid_t mem_type, std::vector<hsize_t>* dims) {
    HINF_CHECK(exists(loc, name), "HDF5: dataset '" + name + "' is missing (file written by another version?)");
    Handle dset(check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), "open dataset '" + name + "'"));
    Handle space(check(H5Dget_space(dset.get()), "read the shape of '" + name + "'"));
    int rank = H5Sget_simple_extent_ndims(space.get());
    HINF_CHECK(rank >= 0 && rank <= 8, "HDF5: dataset '" + name + "' has an invalid shape");
    std::vector<hsize_t> d(static_cast<std::size_t>(rank));
    if (rank > 0) H5Sget_simple_extent_dims(space.get(), d.data(), nullptr);
    hsize_t total = 1;
    for (hsize_t x : d) total *= x;
    HINF_CHECK(total < (hsize_t(1) << 30), "HDF5: dataset '" + name + "' is implausibly large");
    // the stored type and storage must match before HDF5 copies: libhdf5 1.10 trusts a damaged
    // layout message and copies past its buffer (found by fuzz/fuzz_checkpoint.cpp). Doubles are read from
    // any integer or floating-point type (records written by other tools: an integer time column), through
    // libhdf5's own conversion; the other element types only from what hinf writes.
    Handle ftype(check(H5Dget_type(dset.get()), "read the type of '" + name + "'"));
    const H5T_class_t fclass = H5Tget_class(ftype.get());
    const std::size_t fsize = H5Tget_size(ftype.get());
    const bool any_numeric = std::is_same_v<T, double>;
    const bool type_ok = any_numeric ? ((fclass == H5T_FLOAT && (fsize == 2 || fsize == 4 || fsize == 8)) ||
                                        (fclass == H5T_INTEGER && (fsize == 1 || fsize == 2 || fsize == 4 || fsize == 8)))
                                     : (fclass == (std::is_floating_point_v<T> ? H5T_FLOAT : H5T_INTEGER) &&
                                        (fsize == 4 || fsize == 8));
    HINF_CHECK(type_ok, any_numeric ? "HDF5: dataset '" + name + "' is not numeric (an integer or floating-point type "
                                          "is needed; damaged file?)"
                                    : "HDF5: dataset '" + name + "' has an unexpected element type (damaged file?)");
    Handle dcpl(check(H5Dget_create_plist(dset.get()), "read the layout of '" + name + "'"));
    // a dataset larger than its file comes from a damaged header; a compressed one (gzip, as h5py writes
    // with compression="gzip") holds at most deflate's ratio of 1032 : 1
    bool compressed = false;
    const int nfilters = H5Pget_nfilters(dcpl.get());
    for (int i = 0; i < nfilters; ++i) {
        unsigned flags = 0;
        std::size_t nelmts = 0;
        const H5Z_filter_t id = H5Pget_filter2(dcpl.get(), unsigned(i), &flags, &nelmts, nullptr, 0, nullptr, nullptr);
        if (id != H5Z_FILTER_FLETCHER32 && id != H5Z_FILTER_SHUFFLE) compressed = true;
    }
    HINF_CHECK(total * fsize <= (compressed ? 1032 : 1) * file_size(loc),
               "HDF5: dataset '" + name + "' claims more data than its file holds (damaged file)");
    const H5D_layout_t layout = H5Pget_layout(dcpl.get());
    HINF_CHECK(layout == H5D_COMPACT || layout == H5D_CONTIGUOUS || layout == H5D_CHUNKED,
               "HDF5: dataset '" + name + "' has an unknown storage layout (damaged file)");
    if (layout == H5D_CHUNKED) {  // a chunk larger than hinf writes makes libhdf5 copy past its buffer
        std::vector<hsize_t> chunk(d.size() + 1, 0), maxd(d.size(), 0);
        if (rank > 0) H5Sget_simple_extent_dims(space.get(), d.data(), maxd.data());
        const int crank = H5Pget_chunk(dcpl.get(), rank + 1, chunk.data());
        bool ok = crank == rank;
        for (int i = 0; ok && i < rank; ++i)
            ok = chunk[i] >= 1 && chunk[i] <= (maxd[i] == H5S_UNLIMITED ? hsize_t(4096) : std::max<hsize_t>(d[i], 1));
        HINF_CHECK(ok, "HDF5: dataset '" + name + "' has a damaged chunk layout");
    } else {
        HINF_CHECK(H5Dget_storage_size(dset.get()) >= total * fsize,
                   "HDF5: dataset '" + name + "' stores less data than its shape needs (damaged or truncated file)");
    }
    std::vector<T> out(static_cast<std::size_t>(total));
    if (total > 0)
        check_status(H5Dread(dset.get(), mem_type, H5S_ALL, H5S_ALL, H5P_DEFAULT, out.data()),
                     "read dataset '" + name + "' (checksum mismatch or truncated file)");
    if (dims) *dims = d;
    return out;
}

Handle open_attr(hid_t loc, const std::string& name) {
    HINF_CHECK(has_attr(loc, name), "HDF5: attribute '" + name + "' is missing (file written by another version?)");
    return Handle(check(H5Aopen(loc, name.c_str(), H5P_DEFAULT), "open attribute '" + name + "'"));
}

void replace_attr(hid_t loc, const std::string& name) {
    if (H5Aexists(loc, name.c_str()) > 0) H5Adelete(loc, name.c_str());
}

}  // namespace

void Handle::reset() {
    if (id_ < 0) return;
    switch (H5Iget_type(id_)) {
        case H5I_FILE: H5Fclose(id_); break;
        case H5I_GROUP: H5Gclose(id_); break;
        case H5I_DATASET: H5Dclose(id_); break;
        case H5I_DATASPACE: H5Sclose(id_); break;
        case H5I_ATTR: H5Aclose(id_); break;
        case H5I_GENPROP_LST: H5Pclose(id_); break;
        case H5I_DATATYPE: H5Tclose(id_); break;
        default: break;
    }
    id_ = H5I_INVALID_HID;
}

Handle create_file(const std::string& path) {
    hid_t id = H5Fcreate(path.c_str(), H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    HINF_CHECK(id >= 0, "cannot create HDF5 file '" + path + "' (does the directory exist and is it writable?)");
    return Handle(id);
}

Handle open_file(const std::string& path, bool writable) {
    check_input_file(path, "file");
    HINF_CHECK(H5Fis_hdf5(path.c_str()) > 0, "'" + path + "' is not an HDF5 file (truncated, or the wrong file?)");
    hid_t id = H5Fopen(path.c_str(), writable ? H5F_ACC_RDWR : H5F_ACC_RDONLY, H5P_DEFAULT);
    HINF_CHECK(id >= 0, "cannot open HDF5 file '" + path + "' (damaged or truncated?)");
    return Handle(id);
}

void flush(hid_t loc) { check_status(H5Fflush(loc, H5F_SCOPE_GLOBAL), "flush file"); }

Handle create_group(hid_t loc, const std::string& name) {
    return Handle(check(H5Gcreate2(loc, name.c_str(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                        "create group '" + name + "'"));
}

Handle open_group(hid_t loc, const std::string& name) {
    HINF_CHECK(exists(loc, name), "HDF5: group '" + name + "' is missing (file written by another version?)");
    return Handle(check(H5Gopen2(loc, name.c_str(), H5P_DEFAULT), "open group '" + name + "'"));
}

bool exists(hid_t loc, const std::string& path) {
    // Check each prefix: H5Lexists fails on a missing intermediate group.
    std::size_t pos = 0;
    while (true) {
        std::size_t next = path.find('/', pos);
        std::string prefix = path.substr(0, next);
        if (!prefix.empty() && H5Lexists(loc, prefix.c_str(), H5P_DEFAULT) <= 0) return false;
        if (next == std::string::npos) return true;
        pos = next + 1;
    }
}

void write_doubles(hid_t loc, const std::string& name, const double* data, const std::vector<hsize_t>& dims,
                   const std::string& units, const std::string& meaning, bool checksum) {
    write_typed(loc, name, H5T_IEEE_F64LE, H5T_NATIVE_DOUBLE, data, dims, units, meaning, checksum);
}

void write_floats(hid_t loc, const std::string& name, const float* data, const std::vector<hsize_t>& dims,
                  const std::string& units, const std::string& meaning, bool checksum) {
    write_typed(loc, name, H5T_IEEE_F32LE, H5T_NATIVE_FLOAT, data, dims, units, meaning, checksum);
}

void write_int64s(hid_t loc, const std::string& name, const std::int64_t* data, const std::vector<hsize_t>& dims,
                  const std::string& meaning) {
    write_typed(loc, name, H5T_STD_I64LE, H5T_NATIVE_INT64, data, dims, "", meaning, false);
}

void write_string(hid_t loc, const std::string& name, const std::string& text, const std::string& meaning) {
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.get(), text.empty() ? 1 : text.size());
    H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
    Handle space(H5Screate(H5S_SCALAR));
    Handle dset(check(H5Dcreate2(loc, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT),
                      "create dataset '" + name + "'"));
    std::string buf = text.empty() ? std::string(1, '\0') : text;
    check_status(H5Dwrite(dset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()),
                 "write dataset '" + name + "'");
    if (!meaning.empty()) set_attr(dset.get(), "meaning", meaning);
}

std::vector<double> read_doubles(hid_t loc, const std::string& name, std::vector<hsize_t>* dims) {
    return read_typed<double>(loc, name, H5T_NATIVE_DOUBLE, dims);
}
std::vector<float> read_floats(hid_t loc, const std::string& name, std::vector<hsize_t>* dims) {
    return read_typed<float>(loc, name, H5T_NATIVE_FLOAT, dims);
}
std::vector<std::int64_t> read_int64s(hid_t loc, const std::string& name, std::vector<hsize_t>* dims) {
    return read_typed<std::int64_t>(loc, name, H5T_NATIVE_INT64, dims);
}

std::string read_string(hid_t loc, const std::string& name) {
    HINF_CHECK(exists(loc, name), "HDF5: dataset '" + name + "' is missing");
    Handle dset(check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), "open dataset '" + name + "'"));
    Handle type(H5Dget_type(dset.get()));
    HINF_CHECK(H5Tget_class(type.get()) == H5T_STRING && !H5Tis_variable_str(type.get()),
               "HDF5: dataset '" + name + "' is not a fixed-length string");
    std::size_t size = H5Tget_size(type.get());
    HINF_CHECK(size < (1u << 26) && size <= file_size(loc), "HDF5: string '" + name + "' is implausibly large");
    std::string buf(size, '\0');
    check_status(H5Dread(dset.get(), type.get(), H5S_ALL, H5S_ALL, H5P_DEFAULT, buf.data()), "read '" + name + "'");
    buf.resize(std::strlen(buf.c_str()));
    return buf;
}

void set_attr(hid_t loc, const std::string& name, double value) {
    replace_attr(loc, name);
    Handle space(H5Screate(H5S_SCALAR));
    Handle a(check(H5Acreate2(loc, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                   "create attribute '" + name + "'"));
    check_status(H5Awrite(a.get(), H5T_NATIVE_DOUBLE, &value), "write attribute '" + name + "'");
}

void set_attr(hid_t loc, const std::string& name, std::int64_t value) {
    replace_attr(loc, name);
    Handle space(H5Screate(H5S_SCALAR));
    Handle a(check(H5Acreate2(loc, name.c_str(), H5T_STD_I64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                   "create attribute '" + name + "'"));
    check_status(H5Awrite(a.get(), H5T_NATIVE_INT64, &value), "write attribute '" + name + "'");
}

void set_attr(hid_t loc, const std::string& name, const std::string& value) {
    replace_attr(loc, name);
    Handle type(H5Tcopy(H5T_C_S1));
    H5Tset_size(type.get(), value.empty() ? 1 : value.size());
    H5Tset_strpad(type.get(), H5T_STR_NULLPAD);
    Handle space(H5Screate(H5S_SCALAR));
    Handle a(check(H5Acreate2(loc, name.c_str(), type.get(), space.get(), H5P_DEFAULT, H5P_DEFAULT),
                   "create attribute '" + name + "'"));
    std::string buf = value.empty() ? std::string(1, '\0') : value;
    check_status(H5Awrite(a.get(), type.get(), buf.data()), "write attribute '" + name + "'");
}

void set_text(hid_t loc, const std::string& name, const std::string& value) {
    if (H5Aexists(loc, name.c_str()) > 0) check_status(H5Adelete(loc, name.c_str()), "replace '" + name + "'");
    if (exists(loc, name)) check_status(H5Ldelete(loc, name.c_str(), H5P_DEFAULT), "replace '" + name + "'");
    if (value.size() <= kAttrTextMax) set_attr(loc, name, value);
    else write_string(loc, name, value, "text too long for an attribute");
}

bool has_text(hid_t loc, const std::string& name) { return has_attr(loc, name) || exists(loc, name); }

std::string get_text(hid_t loc, const std::string& name) {
    return has_attr(loc, name) ? get_attr_string(loc, name) : read_string(loc, name);
}

void set_attr(hid_t loc, const std::string& name, const char* value) { set_attr(loc, name, std::string(value)); }

void set_attr(hid_t loc, const std::string& name, const std::vector<double>& value) {
    replace_attr(loc, name);
    hsize_t n = value.size();
    Handle space(H5Screate_simple(1, &n, nullptr));
    Handle a(check(H5Acreate2(loc, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, H5P_DEFAULT),
                   "create attribute '" + name + "'"));
    check_status(H5Awrite(a.get(), H5T_NATIVE_DOUBLE, value.data()), "write attribute '" + name + "'");
}

bool has_attr(hid_t loc, const std::string& name) { return H5Aexists(loc, name.c_str()) > 0; }

double get_attr_double(hid_t loc, const std::string& name) {
    Handle a = open_attr(loc, name);
    double v = 0;
    check_status(H5Aread(a.get(), H5T_NATIVE_DOUBLE, &v), "read attribute '" + name + "'");
    return v;
}

std::int64_t get_attr_int(hid_t loc, const std::string& name) {
    Handle a = open_attr(loc, name);
    std::int64_t v = 0;
    check_status(H5Aread(a.get(), H5T_NATIVE_INT64, &v), "read attribute '" + name + "'");
    return v;
}

std::string get_attr_string(hid_t loc, const std::string& name) {
    Handle a = open_attr(loc, name);
    Handle type(H5Aget_type(a.get()));
    HINF_CHECK(H5Tget_class(type.get()) == H5T_STRING && !H5Tis_variable_str(type.get()),
               "HDF5: attribute '" + name + "' is not a fixed-length string");
    std::size_t size = H5Tget_size(type.get());
    std::string buf(size, '\0');
    check_status(H5Aread(a.get(), type.get(), buf.data()), "read attribute '" + name + "'");
    buf.resize(std::strlen(buf.c_str()));
    return buf;
}

std::vector<double> get_attr_doubles(hid_t loc, const std::string& name) {
    Handle a = open_attr(loc, name);
    Handle space(H5Aget_space(a.get()));
    hssize_t n = H5Sget_simple_extent_npoints(space.get());
    HINF_CHECK(n >= 0 && n < (1 << 20), "HDF5: attribute '" + name + "' has an invalid size");
    std::vector<double> v(static_cast<std::size_t>(n));
    if (n > 0) check_status(H5Aread(a.get(), H5T_NATIVE_DOUBLE, v.data()), "read attribute '" + name + "'");
    return v;
}

RowWriter RowWriter::create(hid_t loc, const std::string& name, hsize_t cols, const std::string& units,
                            const std::string& meaning) {
    RowWriter w;
    w.cols_ = cols;
    w.one_d_ = (cols == 1);
    int rank = w.one_d_ ? 1 : 2;
    hsize_t dims[2] = {0, cols}, maxdims[2] = {H5S_UNLIMITED, cols};
    hsize_t chunk[2] = {std::max<hsize_t>(1, 4096 / (cols * 8)) * 8, cols};
    Handle space(check(H5Screate_simple(rank, dims, maxdims), "create dataspace for " + name));
    Handle dcpl(H5Pcreate(H5P_DATASET_CREATE));
    check_status(H5Pset_chunk(dcpl.get(), rank, chunk), "set chunking for " + name);
    w.dset_ = Handle(check(H5Dcreate2(loc, name.c_str(), H5T_IEEE_F64LE, space.get(), H5P_DEFAULT, dcpl.get(),
                                      H5P_DEFAULT),
                           "create dataset '" + name + "'"));
    if (!units.empty()) set_attr(w.dset_.get(), "units", units);
    if (!meaning.empty()) set_attr(w.dset_.get(), "meaning", meaning);
    return w;
}

RowWriter RowWriter::open_truncated(hid_t loc, const std::string& name, hsize_t rows) {
    RowWriter w;
    HINF_CHECK(exists(loc, name), "HDF5: dataset '" + name + "' is missing from the trajectory file");
    w.dset_ = Handle(check(H5Dopen2(loc, name.c_str(), H5P_DEFAULT), "open dataset '" + name + "'"));
    Handle space(H5Dget_space(w.dset_.get()));
    int rank = H5Sget_simple_extent_ndims(space.get());
    hsize_t dims[2] = {0, 1};
    H5Sget_simple_extent_dims(space.get(), dims, nullptr);
    w.one_d_ = (rank == 1);
    w.cols_ = w.one_d_ ? 1 : dims[1];
    HINF_CHECK(dims[0] >= rows, "trajectory dataset '" + name + "' has " + std::to_string(dims[0]) +
                                    " rows but the checkpoint needs " + std::to_string(rows) +
                                    " (the trajectory file is older than the checkpoint)");
    w.rows_ = rows;
    hsize_t newdims[2] = {rows, w.cols_};
    check_status(H5Dset_extent(w.dset_.get(), newdims), "truncate dataset '" + name + "'");
    return w;
}

void RowWriter::append(const double* row) {
    hsize_t newdims[2] = {rows_ + 1, cols_};
    check_status(H5Dset_extent(dset_.get(), newdims), "extend dataset");
    Handle fspace(H5Dget_space(dset_.get()));
    hsize_t start[2] = {rows_, 0}, count[2] = {1, cols_};
    H5Sselect_hyperslab(fspace.get(), H5S_SELECT_SET, start, nullptr, count, nullptr);
    Handle mspace(H5Screate_simple(one_d_ ? 1 : 2, count, nullptr));
    check_status(H5Dwrite(dset_.get(), H5T_NATIVE_DOUBLE, mspace.get(), fspace.get(), H5P_DEFAULT, row),
                 "append a row");
    ++rows_;
}

}  // namespace hinf::h5
