/* startup.h - what startup.c offers the firmware. */
#ifndef STARTUP_H
#define STARTUP_H

/* Deepest stack use since reset (bytes), from the painted words no longer intact. */
unsigned long stack_peak(void);
/* Size of the stack region (bytes); stack_peak() == stack_size() means it overflowed. */
unsigned long stack_size(void);

#endif /* STARTUP_H */
