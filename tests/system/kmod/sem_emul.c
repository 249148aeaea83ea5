// SPDX-License-Identifier: GPL-2.0
/*
 * sem_emul: an emulated SEM behind Comedi, for sempose's system test.
 *
 * Two analog outputs deflect a virtual beam over a scene image (a P5 PGM handed over at
 * load time through the firmware loader, module parameter `scene`, default sem_scene.pgm);
 * two analog inputs return the detector signal at the beam: channel 0 with shot noise
 * (`electrons_white` detected electrons per sample at white when the AI scan period is
 * `ref_dwell_ns`, in proportion to the period otherwise, as a detector integrating the beam
 * current over the dwell; Poisson approximated by a Gaussian of the same mean and variance),
 * channel 1 noise-free (lets a test check the geometry).
 *
 * Geometry: the AO span (±10 V, codes 0..65535) covers the scene; the beam is on scene pixel
 * floor(code * width / 65536) (rows likewise, code 0 at the top row).
 * Detector: 0..10 V; white (255) at 5 V mean, black at 0 V, at every dwell (the mean follows the
 * beam current, the noise shrinks as the dwell grows).
 *
 * Commands, paced by one high-resolution timer (`tick_us`) that produces, at each tick, every
 * AI scan whose time has passed, and for each AI scan first takes one AO scan (X, Y) while the
 * AO command runs: AO and AI are locked sample for sample, as on a card whose AO clock is
 * derived from the AI clock.
 *   AI (subdevice 0): start TRIG_NOW or TRIG_INT, scan_begin TRIG_TIMER (>= 1000 ns, 1 ns
 *      step), convert TRIG_NOW, scan_end TRIG_COUNT, stop TRIG_COUNT or TRIG_NONE.
 *   AO (subdevice 1): start TRIG_INT or TRIG_EXT (starts with the AI command: "AI start
 *      trigger"), scan_begin TRIG_TIMER (the AI clock drives it), stop TRIG_COUNT.
 * Single AO writes move the beam; single AI reads sample at the beam.
 * stall_after_scans / fail_after_scans make an AI command stop delivering (still running) or
 * stop with an error part-way, for the scan source's timeout and early-stop paths.
 */
#include <linux/module.h>
#include <linux/hrtimer.h>
#include <linux/ktime.h>
#include <linux/firmware.h>
#include <linux/prandom.h>
#include <linux/slab.h>
#include <linux/vmalloc.h>
#include <linux/device.h>
#include <linux/comedi/comedidev.h>

static char *scene = "sem_scene.pgm";
module_param(scene, charp, 0444);
MODULE_PARM_DESC(scene, "scene image (P5 PGM, 8 bit) under /lib/firmware");
static unsigned int electrons_white = 20;
module_param(electrons_white, uint, 0444);
MODULE_PARM_DESC(electrons_white, "mean detected electrons per AI sample at white (channel 0) at ref_dwell_ns");
static unsigned int ref_dwell_ns = 2000;
module_param(ref_dwell_ns, uint, 0444);
MODULE_PARM_DESC(ref_dwell_ns, "AI scan period (ns) at which a sample at white holds electrons_white electrons");
static unsigned int tick_us = 250;
module_param(tick_us, uint, 0444);
MODULE_PARM_DESC(tick_us, "pacing timer period in microseconds");

/* Fault injection for the source's error paths (0: off; writable at run time). */
static unsigned int stall_after_scans;
module_param(stall_after_scans, uint, 0644);
MODULE_PARM_DESC(stall_after_scans, "AI stops delivering after this many scans, still running (a lost clock)");
static unsigned int fail_after_scans;
module_param(fail_after_scans, uint, 0644);
MODULE_PARM_DESC(fail_after_scans, "AI stops with an error after this many scans (an overrun)");

/* What the last AI command did (read-only, for a test's diagnosis). */
static unsigned int last_ai_scans, last_ao_scans, last_stale_scans;
module_param(last_ai_scans, uint, 0444);
module_param(last_ao_scans, uint, 0444);
module_param(last_stale_scans, uint, 0444);
MODULE_PARM_DESC(last_stale_scans, "AI scans of the last command taken while AO ran but had no sample");

#define SEM_MIN_PERIOD_NS 1000

struct sem_priv {
	struct comedi_device *dev;
	struct hrtimer timer;
	spinlock_t lock;
	u8 *img;
	unsigned int w, h;
	unsigned int beam_x, beam_y;	/* AO codes */
	unsigned int ao_last[2];
	bool ai_running, ao_armed, ao_running;
	u64 t0_ns;			/* AI start */
	u64 period_ns;
	u64 scans_done;
	struct rnd_state rnd;
	s64 white_q12;			/* detected electrons per sample at white at this dwell, Q12 */
	s64 mean_q12[256];		/* detected electrons per grey level, Q12 */
	u32 sigma_q12[256];		/* their shot-noise sigma, Q12 */
	s32 gauss_q12[4096];		/* N(0, 1) deviates, Q12 */
};

static struct class *sem_class;
static struct device *sem_dev;

static const struct comedi_lrange sem_ai_range = { 1, { UNI_RANGE(10) } };

static unsigned int sem_pixel(struct sem_priv *p)
{
	unsigned int x = (unsigned int)(((u64)p->beam_x * p->w) >> 16);
	unsigned int y = (unsigned int)(((u64)p->beam_y * p->h) >> 16);

	return p->img[y * p->w + x];
}

/*
 * Per sample only a table look-up: sigma (in electrons, Q12) per grey level, and 4096
 * standard normal deviates (Q12, Irwin-Hall sums of 12 uniforms) made at attach. A sample
 * costs one prandom call, so pacing a few hundred thousand samples a second stays cheap even
 * in an emulated (TCG) guest.
 */
static unsigned short sem_sample(struct sem_priv *p, unsigned int chan)
{
	unsigned int s = sem_pixel(p);
	s64 e_q12, code;

	if (chan == 1)
		return (unsigned short)(s * 32767 / 255);
	e_q12 = p->mean_q12[s] + (s64)p->sigma_q12[s] * p->gauss_q12[prandom_u32_state(&p->rnd) >> 20] / 4096;
	/* white mean at mid scale: code = electrons * 32767 / electrons at white */
	code = e_q12 * 32767 / p->white_q12;
	return (unsigned short)clamp_val(code, 0, 65535);
}

/* The dose of an AI scan period: electrons_white at ref_dwell_ns, in proportion otherwise. */
static void sem_set_dose(struct sem_priv *p, u64 period_ns)
{
	u64 ew = electrons_white ? electrons_white : 1;
	u64 ref = ref_dwell_ns ? ref_dwell_ns : 1;
	unsigned int g;

	period_ns = clamp_val(period_ns, SEM_MIN_PERIOD_NS, 1000000000ULL);
	p->white_q12 = max_t(s64, 1, div64_u64(ew * period_ns * 4096, ref));
	for (g = 0; g < 256; g++) {
		p->mean_q12[g] = p->white_q12 * g / 255;
		p->sigma_q12[g] = int_sqrt64((u64)p->mean_q12[g] * 4096);
	}
}

static void sem_make_tables(struct sem_priv *p)
{
	unsigned int i, k;

	sem_set_dose(p, ref_dwell_ns);
	for (i = 0; i < 4096; i++) {
		int sum = 0;

		for (k = 0; k < 12; k++)
			sum += prandom_u32_state(&p->rnd) >> 20;
		p->gauss_q12[i] = sum - 6 * 4096;
	}
}

static enum hrtimer_restart sem_tick(struct hrtimer *t)
{
	struct sem_priv *p = container_of(t, struct sem_priv, timer);
	struct comedi_device *dev = p->dev;
	struct comedi_subdevice *ai = &dev->subdevices[0];
	struct comedi_subdevice *ao = &dev->subdevices[1];
	struct comedi_cmd *cmd = &ai->async->cmd;
	unsigned long flags;
	u64 due, now = ktime_get_ns();
	bool more = true, ao_events = false;

	spin_lock_irqsave(&p->lock, flags);
	if (!p->ai_running) {
		spin_unlock_irqrestore(&p->lock, flags);
		return HRTIMER_NORESTART;
	}
	due = now > p->t0_ns ? div64_u64(now - p->t0_ns, p->period_ns) : 0;
	while (p->scans_done < due) {
		unsigned short data[16];
		unsigned int i;

		if (cmd->stop_src == TRIG_COUNT && p->scans_done >= cmd->stop_arg)
			break;
		if (fail_after_scans && p->scans_done >= fail_after_scans) {
			ai->async->events |= COMEDI_CB_ERROR;
			more = false;
			break;
		}
		if (stall_after_scans && p->scans_done >= stall_after_scans)
			break;
		if (p->ao_running) {
			unsigned short xy[2];
			unsigned int got = comedi_buf_read_samples(ao, xy, 2);	/* bytes, not samples */

			if (got == 0 && ao->async->scans_done < ao->async->cmd.stop_arg) {
				/* not there yet (the writer lags): hold the beam, never skip */
				last_stale_scans++;
			} else if (got == comedi_samples_to_bytes(ao, 2)) {
				last_ao_scans++;
				p->beam_x = xy[0];
				p->beam_y = xy[1];
				if (ao->async->cmd.stop_src == TRIG_COUNT &&
				    ao->async->scans_done >= ao->async->cmd.stop_arg) {
					ao->async->events |= COMEDI_CB_EOA;
					p->ao_running = false;
					ao_events = true;
				}
			} else {
				ao->async->events |= COMEDI_CB_OVERFLOW;	/* underrun */
				p->ao_running = false;
				ao_events = true;
			}
		}
		for (i = 0; i < cmd->chanlist_len && i < ARRAY_SIZE(data); i++)
			data[i] = sem_sample(p, CR_CHAN(cmd->chanlist[i]));
		if (comedi_buf_write_samples(ai, data, cmd->chanlist_len) == 0) {
			more = false;	/* overrun: the event is set by the core */
			break;
		}
		last_ai_scans++;
		p->scans_done++;
	}
	if (cmd->stop_src == TRIG_COUNT && p->scans_done >= cmd->stop_arg) {
		ai->async->events |= COMEDI_CB_EOA;
		more = false;
	}
	if (!more)
		p->ai_running = false;
	spin_unlock_irqrestore(&p->lock, flags);

	if (ao_events)
		comedi_handle_events(dev, ao);
	comedi_handle_events(dev, ai);
	if (!more)
		return HRTIMER_NORESTART;
	hrtimer_forward_now(t, ns_to_ktime((u64)tick_us * 1000));
	return HRTIMER_RESTART;
}

static void sem_start_ai(struct sem_priv *p)
{
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->t0_ns = ktime_get_ns();
	p->scans_done = 0;
	last_ai_scans = last_ao_scans = last_stale_scans = 0;
	p->ai_running = true;
	if (p->ao_armed) {	/* AO waits for the AI start trigger */
		p->ao_armed = false;
		p->ao_running = true;
	}
	spin_unlock_irqrestore(&p->lock, flags);
	hrtimer_start(&p->timer, ns_to_ktime((u64)tick_us * 1000), HRTIMER_MODE_REL);
}

static int sem_cmdtest(struct comedi_device *dev, struct comedi_subdevice *s,
		       struct comedi_cmd *cmd)
{
	bool is_ai = s->index == 0;
	int err = 0;

	err |= comedi_check_trigger_src(&cmd->start_src,
					is_ai ? (TRIG_NOW | TRIG_INT) : (TRIG_INT | TRIG_EXT));
	err |= comedi_check_trigger_src(&cmd->scan_begin_src, TRIG_TIMER);
	err |= comedi_check_trigger_src(&cmd->convert_src, TRIG_NOW);
	err |= comedi_check_trigger_src(&cmd->scan_end_src, TRIG_COUNT);
	err |= comedi_check_trigger_src(&cmd->stop_src,
					is_ai ? (TRIG_COUNT | TRIG_NONE) : TRIG_COUNT);
	if (err)
		return 1;
	err |= comedi_check_trigger_is_unique(cmd->start_src);
	err |= comedi_check_trigger_is_unique(cmd->stop_src);
	if (err)
		return 2;
	if (cmd->start_src != TRIG_EXT)
		err |= comedi_check_trigger_arg_is(&cmd->start_arg, 0);
	err |= comedi_check_trigger_arg_min(&cmd->scan_begin_arg, SEM_MIN_PERIOD_NS);
	err |= comedi_check_trigger_arg_is(&cmd->convert_arg, 0);
	err |= comedi_check_trigger_arg_min(&cmd->chanlist_len, 1);
	err |= comedi_check_trigger_arg_is(&cmd->scan_end_arg, cmd->chanlist_len);
	if (cmd->stop_src == TRIG_COUNT)
		err |= comedi_check_trigger_arg_min(&cmd->stop_arg, 1);
	else
		err |= comedi_check_trigger_arg_is(&cmd->stop_arg, 0);
	if (!is_ai)
		err |= comedi_check_trigger_arg_is(&cmd->chanlist_len, 2);
	if (err)
		return 3;
	return 0;
}

static int sem_ai_inttrig(struct comedi_device *dev, struct comedi_subdevice *s,
			  unsigned int trig_num)
{
	if (trig_num != s->async->cmd.start_arg)
		return -EINVAL;
	s->async->inttrig = NULL;
	sem_start_ai(dev->private);
	return 1;
}

static int sem_ai_cmd(struct comedi_device *dev, struct comedi_subdevice *s)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->period_ns = s->async->cmd.scan_begin_arg;
	sem_set_dose(p, p->period_ns);
	spin_unlock_irqrestore(&p->lock, flags);
	if (s->async->cmd.start_src == TRIG_INT)
		s->async->inttrig = sem_ai_inttrig;
	else
		sem_start_ai(p);
	return 0;
}

static int sem_ai_cancel(struct comedi_device *dev, struct comedi_subdevice *s)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->ai_running = false;
	spin_unlock_irqrestore(&p->lock, flags);
	/* may run inside the timer callback (events): never wait for it here */
	hrtimer_try_to_cancel(&p->timer);
	return 0;
}

static int sem_ao_inttrig(struct comedi_device *dev, struct comedi_subdevice *s,
			  unsigned int trig_num)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;

	if (trig_num != s->async->cmd.start_arg)
		return -EINVAL;
	s->async->inttrig = NULL;
	spin_lock_irqsave(&p->lock, flags);
	p->ao_armed = false;
	p->ao_running = true;
	spin_unlock_irqrestore(&p->lock, flags);
	return 1;
}

static int sem_ao_cmd(struct comedi_device *dev, struct comedi_subdevice *s)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->ao_running = false;
	p->ao_armed = s->async->cmd.start_src == TRIG_EXT;
	spin_unlock_irqrestore(&p->lock, flags);
	if (s->async->cmd.start_src == TRIG_INT)
		s->async->inttrig = sem_ao_inttrig;
	return 0;
}

static int sem_ao_cancel(struct comedi_device *dev, struct comedi_subdevice *s)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;

	spin_lock_irqsave(&p->lock, flags);
	p->ao_armed = false;
	p->ao_running = false;
	spin_unlock_irqrestore(&p->lock, flags);
	return 0;
}

static int sem_ao_insn_write(struct comedi_device *dev, struct comedi_subdevice *s,
			     struct comedi_insn *insn, unsigned int *data)
{
	struct sem_priv *p = dev->private;
	unsigned int chan = CR_CHAN(insn->chanspec);
	unsigned long flags;
	unsigned int i;

	spin_lock_irqsave(&p->lock, flags);
	for (i = 0; i < insn->n; i++) {
		p->ao_last[chan] = data[i];
		if (chan == 0)
			p->beam_x = data[i];
		else
			p->beam_y = data[i];
	}
	spin_unlock_irqrestore(&p->lock, flags);
	return insn->n;
}

static int sem_ao_insn_read(struct comedi_device *dev, struct comedi_subdevice *s,
			    struct comedi_insn *insn, unsigned int *data)
{
	struct sem_priv *p = dev->private;
	unsigned int i;

	for (i = 0; i < insn->n; i++)
		data[i] = p->ao_last[CR_CHAN(insn->chanspec)];
	return insn->n;
}

static int sem_ai_insn_read(struct comedi_device *dev, struct comedi_subdevice *s,
			    struct comedi_insn *insn, unsigned int *data)
{
	struct sem_priv *p = dev->private;
	unsigned long flags;
	unsigned int i;

	spin_lock_irqsave(&p->lock, flags);
	for (i = 0; i < insn->n; i++)
		data[i] = sem_sample(p, CR_CHAN(insn->chanspec));
	spin_unlock_irqrestore(&p->lock, flags);
	return insn->n;
}

/* P5, 8 bit, comments allowed; enough for the test's own scene file. */
static int sem_parse_pgm(struct sem_priv *p, const u8 *d, size_t n)
{
	unsigned int v[3] = { 0, 0, 0 };
	size_t i = 2;
	int k;

	if (n < 2 || d[0] != 'P' || d[1] != '5')
		return -EINVAL;
	for (k = 0; k < 3; k++) {
		while (i < n && (d[i] == ' ' || d[i] == '\n' || d[i] == '\r' || d[i] == '\t' || d[i] == '#')) {
			if (d[i] == '#')
				while (i < n && d[i] != '\n')
					i++;
			else
				i++;
		}
		if (i >= n || d[i] < '0' || d[i] > '9')
			return -EINVAL;
		while (i < n && d[i] >= '0' && d[i] <= '9')
			v[k] = v[k] * 10 + (d[i++] - '0');
	}
	i++;	/* one whitespace after maxval */
	if (v[0] == 0 || v[1] == 0 || v[0] > 16384 || v[1] > 16384 || v[2] != 255 ||
	    n < i + (size_t)v[0] * v[1])
		return -EINVAL;
	p->img = vmalloc((size_t)v[0] * v[1]);
	if (!p->img)
		return -ENOMEM;
	memcpy(p->img, d + i, (size_t)v[0] * v[1]);
	p->w = v[0];
	p->h = v[1];
	return 0;
}

static int sem_auto_attach(struct comedi_device *dev, unsigned long context)
{
	struct sem_priv *p;
	struct comedi_subdevice *s;
	const struct firmware *fw;
	int ret;

	p = comedi_alloc_devpriv(dev, sizeof(*p));
	if (!p)
		return -ENOMEM;
	p->dev = dev;
	spin_lock_init(&p->lock);
	prandom_seed_state(&p->rnd, 0x5e3e3c0de5ULL);
	sem_make_tables(p);
	hrtimer_init(&p->timer, CLOCK_MONOTONIC, HRTIMER_MODE_REL);
	p->timer.function = sem_tick;
	p->beam_x = p->beam_y = 32768;

	ret = request_firmware(&fw, scene, dev->class_dev);
	if (ret) {
		dev_err(dev->class_dev, "scene %s: not found under /lib/firmware (%d)\n", scene, ret);
		return ret;
	}
	ret = sem_parse_pgm(p, fw->data, fw->size);
	release_firmware(fw);
	if (ret) {
		dev_err(dev->class_dev, "scene %s: not an 8-bit P5 PGM\n", scene);
		return ret;
	}

	ret = comedi_alloc_subdevices(dev, 2);
	if (ret)
		return ret;
	s = &dev->subdevices[0];
	dev->read_subdev = s;
	s->type = COMEDI_SUBD_AI;
	s->subdev_flags = SDF_READABLE | SDF_GROUND | SDF_CMD_READ;
	s->n_chan = 2;
	s->maxdata = 0xffff;
	s->range_table = &sem_ai_range;
	s->len_chanlist = 2;
	s->insn_read = sem_ai_insn_read;
	s->do_cmdtest = sem_cmdtest;
	s->do_cmd = sem_ai_cmd;
	s->cancel = sem_ai_cancel;

	s = &dev->subdevices[1];
	dev->write_subdev = s;
	s->type = COMEDI_SUBD_AO;
	s->subdev_flags = SDF_WRITABLE | SDF_GROUND | SDF_CMD_WRITE;
	s->n_chan = 2;
	s->maxdata = 0xffff;
	s->range_table = &range_bipolar10;
	s->len_chanlist = 2;
	s->insn_write = sem_ao_insn_write;
	s->insn_read = sem_ao_insn_read;
	s->do_cmdtest = sem_cmdtest;
	s->do_cmd = sem_ao_cmd;
	s->cancel = sem_ao_cancel;

	dev_info(dev->class_dev, "sem_emul: scene %s %ux%u, %u e-/sample at white at %u ns dwell, tick %u us\n",
		 scene, p->w, p->h, electrons_white, ref_dwell_ns, tick_us);
	return 0;
}

static void sem_detach(struct comedi_device *dev)
{
	struct sem_priv *p = dev->private;

	if (p) {
		p->ai_running = false;
		hrtimer_cancel(&p->timer);
		vfree(p->img);
	}
}

static struct comedi_driver sem_driver = {
	.driver_name = "sem_emul",
	.module = THIS_MODULE,
	.auto_attach = sem_auto_attach,
	.detach = sem_detach,
};

static int __init sem_init(void)
{
	int ret = comedi_driver_register(&sem_driver);

	if (ret)
		return ret;
	sem_class = class_create(THIS_MODULE, "sem_emul");
	if (IS_ERR(sem_class)) {
		ret = PTR_ERR(sem_class);
		goto unregister;
	}
	sem_dev = device_create(sem_class, NULL, MKDEV(0, 0), NULL, "sem_emul");
	if (IS_ERR(sem_dev)) {
		ret = PTR_ERR(sem_dev);
		goto destroy_class;
	}
	ret = comedi_auto_config(sem_dev, &sem_driver, 0);
	if (ret)
		goto destroy_dev;
	return 0;
destroy_dev:
	device_destroy(sem_class, MKDEV(0, 0));
destroy_class:
	class_destroy(sem_class);
unregister:
	comedi_driver_unregister(&sem_driver);
	return ret;
}
module_init(sem_init);

static void __exit sem_exit(void)
{
	comedi_auto_unconfig(sem_dev);
	device_destroy(sem_class, MKDEV(0, 0));
	class_destroy(sem_class);
	comedi_driver_unregister(&sem_driver);
}
module_exit(sem_exit);

MODULE_AUTHOR("sempose system test");
MODULE_DESCRIPTION("Emulated SEM behind Comedi: beam on AO, detector on AI, scene from firmware");
MODULE_LICENSE("GPL");
