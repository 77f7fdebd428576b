// run_batch and the engine's AdvancePool (batch.hpp): simulations advanced side by side on threads
// with the GIL released; a failed member's exception comes back as its Python exception object
// (bind_simulation.cpp's exception_object).
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "convert.hpp"
#include "coopsim/batch.hpp"
#include "generated/docstrings.hpp"
#include "nogil.hpp"

namespace py = pybind11;
using namespace coopsim;
using namespace coopsim::py_convert;
using namespace coopsim::docs;

py::object exception_object(const std::exception_ptr& p);  // bind_simulation.cpp

void bind_batch(py::module_& m) {
  m.def("run_batch", [](const py::list& sims, double t_end, int threads) {
         std::vector<Simulation*> ptrs;
         for (py::handle h : sims) ptrs.push_back(h.cast<Simulation*>());
         std::vector<std::exception_ptr> errs;
         std::vector<double> seconds;
         {
           coopsim::py_nogil::NoGil nogil;
           errs = run_batch(ptrs, t_end, threads, &seconds);
         }
         py::list out;
         py::list secs;
         for (size_t i = 0; i < errs.size(); ++i) {
           out.append(errs[i] ? exception_object(errs[i]) : py::none());
           secs.append(seconds[i]);
         }
         return py::make_tuple(out, secs);
       }, py::arg("sims"), py::arg("t_end"), py::arg("threads") = 0, doc_run_batch);
  py::class_<AdvancePool::Job, std::shared_ptr<AdvancePool::Job>>(m, "AdvanceJob", doc_AdvancePool_Job)
      .def("result", [](AdvancePool::Job& j) {
         { coopsim::py_nogil::NoGil nogil; j.wait(); }
         if (j.failure) std::rethrow_exception(j.failure);
         py::list errs, secs;
         for (size_t i = 0; i < j.errors.size(); ++i) {
           errs.append(j.errors[i] ? exception_object(j.errors[i]) : py::none());
           secs.append(j.seconds[i]);
         }
         return py::make_tuple(errs, secs, j.rows.size() ? py::object(to_numpy(j.rows)) : py::object(py::none()));
       }, "(errors, seconds, rows or None) once done (waits with the GIL released); raises the job's own failure.")
      .def("done", &AdvancePool::Job::done, "Whether the job is done (no wait).");
  py::class_<AdvancePool>(m, "AdvancePool", doc_AdvancePool)
      .def(py::init<int>(), py::arg("threads"), doc_AdvancePool_AdvancePool)
      .def("submit", &AdvancePool::submit, py::arg("sims"), py::arg("t_end"), py::arg("a") = 0, py::arg("b") = 0,
           py::arg("body") = std::string(), py::keep_alive<0, 2>(), doc_AdvancePool_submit)
      .def("run_one", [](AdvancePool& p) {
             coopsim::py_nogil::NoGil nogil;
             return p.run_one();
           }, doc_AdvancePool_run_one)
      .def_property_readonly("threads", &AdvancePool::threads);
}
