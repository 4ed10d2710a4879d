"""The class: courses and their people, class lists, per-course limits and bookings.

* :mod:`.courses` — courses, teachers, students, enrolment codes;
* :mod:`.class_list` — reading a class list (CSV);
* :mod:`.course_settings` — a course's limits during its booked slots;
* :mod:`.bookings` — slots reserving rigs for a course, and the calendar.

Assignments and their marks live in :mod:`thermolab.lab.assignments`; turns at
a rig in :mod:`thermolab.lab.access`, which asks this package whose slot it is.
"""
